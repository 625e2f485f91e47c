//! The packaged binary loaded as an importer loads it (`dlopen` through `libloading`),
//! its functions typed from the FMI 3.0 header (`fmi3FunctionTypes.h`), and a small
//! instance wrapper that collects the FMU's log messages.

use std::ffi::{c_char, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use libloading::Library;

pub type Ptr = *mut c_void;
pub type LogCb = unsafe extern "C" fn(Ptr, i32, *const c_char, *const c_char);
type Instantiate = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_char,
    bool,
    bool,
    bool,
    bool,
    *const u32,
    usize,
    Ptr,
    Option<LogCb>,
    *const c_void,
) -> Ptr;
type Get<T> = unsafe extern "C" fn(Ptr, *const u32, usize, *mut T, usize) -> i32;
type Set<T> = unsafe extern "C" fn(Ptr, *const u32, usize, *const T, usize) -> i32;
type DoStep = unsafe extern "C" fn(Ptr, f64, f64, bool, *mut bool, *mut bool, *mut bool, *mut f64) -> i32;

pub const OK: i32 = 0;
pub const ERROR: i32 = 3;

/// The C functions the tests call.
pub struct Api {
    pub lib: Library,
    pub get_version: unsafe extern "C" fn() -> *const c_char,
    pub instantiate: Instantiate,
    pub instantiate_me: unsafe extern "C" fn(
        *const c_char,
        *const c_char,
        *const c_char,
        bool,
        bool,
        Ptr,
        Option<LogCb>,
    ) -> Ptr,
    pub free: unsafe extern "C" fn(Ptr),
    pub enter_init: unsafe extern "C" fn(Ptr, bool, f64, f64, bool, f64) -> i32,
    pub exit_init: unsafe extern "C" fn(Ptr) -> i32,
    pub terminate: unsafe extern "C" fn(Ptr) -> i32,
    pub reset: unsafe extern "C" fn(Ptr) -> i32,
    pub get_f64: Get<f64>,
    pub set_f64: Set<f64>,
    pub get_i64: Get<i64>,
    pub set_i64: Set<i64>,
    pub get_i32: Get<i32>,
    pub do_step: DoStep,
    pub get_fmu_state: unsafe extern "C" fn(Ptr, *mut Ptr) -> i32,
}

/// An FMU extracted into a directory, its binary loaded.
pub struct Fmu {
    pub dir: PathBuf,
    pub api: Api,
    pub token: String,
}

impl Fmu {
    /// Extract `fmu` into `dir` and load its binary.
    pub fn load(fmu: &Path, dir: &Path) -> Self {
        super::extract(fmu, dir);
        let so = dir.join("binaries/x86_64-linux/simrod.so");
        // SAFETY: the FMU's binary; its initialisers are Rust's and do nothing unusual.
        let lib = unsafe { Library::new(&so) }.unwrap_or_else(|e| panic!("dlopen {}: {e}", so.display()));
        macro_rules! sym {
            ($name:literal) => {
                // SAFETY: the symbol's type is the FMI header's signature of that function.
                *unsafe { lib.get(concat!($name, "\0").as_bytes()) }
                    .unwrap_or_else(|e| panic!("{} not exported: {e}", $name))
            };
        }
        let api = Api {
            get_version: sym!("fmi3GetVersion"),
            instantiate: sym!("fmi3InstantiateCoSimulation"),
            instantiate_me: sym!("fmi3InstantiateModelExchange"),
            free: sym!("fmi3FreeInstance"),
            enter_init: sym!("fmi3EnterInitializationMode"),
            exit_init: sym!("fmi3ExitInitializationMode"),
            terminate: sym!("fmi3Terminate"),
            reset: sym!("fmi3Reset"),
            get_f64: sym!("fmi3GetFloat64"),
            set_f64: sym!("fmi3SetFloat64"),
            get_i64: sym!("fmi3GetInt64"),
            set_i64: sym!("fmi3SetInt64"),
            get_i32: sym!("fmi3GetInt32"),
            do_step: sym!("fmi3DoStep"),
            get_fmu_state: sym!("fmi3GetFMUState"),
            lib,
        };
        let xml = std::fs::read_to_string(dir.join("modelDescription.xml")).expect("modelDescription.xml");
        Self { dir: dir.to_path_buf(), api, token: super::token_of(&xml) }
    }

    /// The resource path an importer passes: `resources/` with a trailing separator.
    pub fn resources(&self) -> String {
        format!("{}/", self.dir.join("resources").display())
    }

    /// A Co-Simulation instance with the right token.
    pub fn instance(&self, name: &str) -> Inst<'_> {
        let token = self.token.clone();
        self.instantiate(name, &token, Some(&self.resources()))
            .unwrap_or_else(|log| panic!("instantiate: {log}"))
    }

    /// Instantiate with the given token and resource path; the log on failure.
    pub fn instantiate(&self, name: &str, token: &str, resources: Option<&str>) -> Result<Inst<'_>, String> {
        let log: Box<Mutex<Vec<String>>> = Box::default();
        let c = |s: &str| CString::new(s).unwrap();
        let (name, token) = (c(name), c(token));
        let res = resources.map(c);
        let env = (&*log as *const Mutex<Vec<String>>).cast_mut().cast::<c_void>();
        // SAFETY: valid strings for the call; `env` points to `log`, which the instance
        // wrapper keeps alive as long as the instance.
        let ptr = unsafe {
            (self.api.instantiate)(
                name.as_ptr(),
                token.as_ptr(),
                res.as_ref().map_or(std::ptr::null(), |r| r.as_ptr()),
                false,
                true,
                false,
                false,
                std::ptr::null(),
                0,
                env,
                Some(collect),
                std::ptr::null(),
            )
        };
        if ptr.is_null() {
            return Err(log.lock().unwrap().join("\n"));
        }
        Ok(Inst { api: &self.api, ptr, log })
    }
}

/// The log callback: appends `[status] category: message` to the instance's log.
pub unsafe extern "C" fn collect(env: Ptr, status: i32, category: *const c_char, message: *const c_char) {
    // SAFETY: `env` is the Mutex<Vec<String>> given at instantiation; the strings are
    // NUL-terminated (FMI).
    let (log, cat, msg) =
        unsafe { (&*env.cast::<Mutex<Vec<String>>>(), CStr::from_ptr(category), CStr::from_ptr(message)) };
    log.lock().unwrap().push(format!("[{status}] {}: {}", cat.to_string_lossy(), msg.to_string_lossy()));
}

/// One instance; freed on drop.
pub struct Inst<'a> {
    pub api: &'a Api,
    pub ptr: Ptr,
    log: Box<Mutex<Vec<String>>>,
}

impl Inst<'_> {
    /// Everything logged so far, one message a line.
    pub fn log(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    /// The last message logged.
    pub fn last(&self) -> String {
        self.log.lock().unwrap().last().cloned().unwrap_or_default()
    }

    /// Enter and exit initialization at t = 0; panics on error.
    pub fn init(&self) {
        // SAFETY: a live instance.
        unsafe {
            assert_eq!(
                (self.api.enter_init)(self.ptr, false, 0.0, 0.0, false, 0.0),
                super::capi::OK,
                "{}",
                self.log()
            );
            assert_eq!((self.api.exit_init)(self.ptr), OK, "{}", self.log());
        }
    }

    /// `fmi3GetFloat64` of `vrs`.
    pub fn get(&self, vrs: &[u32]) -> (i32, Vec<f64>) {
        let mut v = vec![f64::NAN; vrs.len()];
        // SAFETY: arrays of the lengths passed.
        let s = unsafe { (self.api.get_f64)(self.ptr, vrs.as_ptr(), vrs.len(), v.as_mut_ptr(), v.len()) };
        (s, v)
    }

    /// `fmi3SetFloat64`.
    pub fn set(&self, vrs: &[u32], values: &[f64]) -> i32 {
        // SAFETY: arrays of the lengths passed.
        unsafe { (self.api.set_f64)(self.ptr, vrs.as_ptr(), vrs.len(), values.as_ptr(), values.len()) }
    }

    /// `fmi3GetInt64`.
    pub fn get_i64(&self, vrs: &[u32]) -> (i32, Vec<i64>) {
        let mut v = vec![0; vrs.len()];
        // SAFETY: arrays of the lengths passed.
        let s = unsafe { (self.api.get_i64)(self.ptr, vrs.as_ptr(), vrs.len(), v.as_mut_ptr(), v.len()) };
        (s, v)
    }

    /// `fmi3SetInt64`.
    pub fn set_i64(&self, vrs: &[u32], values: &[i64]) -> i32 {
        // SAFETY: arrays of the lengths passed.
        unsafe { (self.api.set_i64)(self.ptr, vrs.as_ptr(), vrs.len(), values.as_ptr(), values.len()) }
    }

    /// `fmi3DoStep(t, h)`; the status and `lastSuccessfulTime`.
    pub fn step(&self, t: f64, h: f64) -> (i32, f64) {
        let (mut a, mut b, mut c, mut last) = (true, true, true, f64::NAN);
        // SAFETY: valid output pointers.
        let s = unsafe { (self.api.do_step)(self.ptr, t, h, false, &mut a, &mut b, &mut c, &mut last) };
        if s == OK {
            assert!(!a && !b && !c, "eventHandlingNeeded, terminateSimulation, earlyReturn must be false");
        }
        (s, last)
    }

    /// `fmi3Reset`.
    pub fn reset(&self) -> i32 {
        // SAFETY: a live instance.
        unsafe { (self.api.reset)(self.ptr) }
    }
}

impl Drop for Inst<'_> {
    fn drop(&mut self) {
        // SAFETY: a live instance, freed once.
        unsafe { (self.api.free)(self.ptr) }
    }
}
