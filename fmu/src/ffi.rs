//! The FMI 3.0 C API: every function of `fmi3Functions.h`, with its exact C signature
//! (FMI 3.0 standard headers, as shipped with FMPy and the FMU Manipulation Toolbox).
//! The only module with `unsafe`: it turns the importer's raw pointers into Rust
//! references and slices and hands them to [`Instance`], which is safe Rust.
//!
//! # Safety contract (the FMI standard's, stated once for every function here)
//!
//! The importer passes, as the standard requires: an `fmi3Instance` it got from
//! `fmi3InstantiateCoSimulation` and has not freed; arrays valid for the lengths it
//! passes with them; NUL-terminated strings; output pointers valid for writing; and it
//! calls one instance from one thread at a time. Within that contract nothing here is
//! undefined behaviour, and beyond it what can be checked is checked: a NULL pointer
//! with a non-zero length, a NULL output pointer, a NULL string, and an instance pointer
//! this library did not hand out (or already freed) are refused with `fmi3Error`
//! (logged through the instance's callback where there is an instance).
//!
//! No panic crosses the boundary: every function runs its body under
//! `std::panic::catch_unwind`; a panic becomes `fmi3Error` with the panic's message in
//! the log, and the instance is left Terminated.
//!
//! Functions of interfaces and capabilities this FMU does not have (Model Exchange,
//! Scheduled Execution, Event Mode, clocks, FMU state, derivatives, configuration mode,
//! variable types it has no variables of) return `fmi3Error` and log why.

#![allow(unsafe_code)]
// The safety contract above applies to every exported function alike.
#![allow(clippy::missing_safety_doc)]
// The C signatures are the standard's.
#![allow(clippy::too_many_arguments, non_snake_case)]

use std::collections::BTreeSet;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Mutex;

use crate::instance::{Instance, LogFn, Logger, Status};

type Fmi3Instance = *mut c_void;
type Fmi3InstanceEnvironment = *mut c_void;
type Fmi3FMUState = *mut c_void;
type Fmi3ValueReference = u32;
type Fmi3String = *const c_char;
type Fmi3Binary = *const u8;
type Fmi3Boolean = bool;
type Fmi3Clock = bool;
/// `fmi3DependencyKind` and `fmi3IntervalQualifier` are C enums: `int`.
type CEnum = c_int;

type LogMessageCallback =
    Option<unsafe extern "C" fn(Fmi3InstanceEnvironment, Status, Fmi3String, Fmi3String)>;
type IntermediateUpdateCallback = Option<
    unsafe extern "C" fn(
        Fmi3InstanceEnvironment,
        f64,
        Fmi3Boolean,
        Fmi3Boolean,
        Fmi3Boolean,
        Fmi3Boolean,
        *mut Fmi3Boolean,
        *mut f64,
    ),
>;
type ClockUpdateCallback = Option<unsafe extern "C" fn(Fmi3InstanceEnvironment)>;
type LockPreemptionCallback = Option<unsafe extern "C" fn()>;
type UnlockPreemptionCallback = Option<unsafe extern "C" fn()>;

/// The instances handed out and not yet freed, by address: a call with any other
/// pointer is refused instead of dereferenced.
static LIVE: Mutex<BTreeSet<usize>> = Mutex::new(BTreeSet::new());

fn live() -> std::sync::MutexGuard<'static, BTreeSet<usize>> {
    // The set stays consistent even if a holder panicked (insert/remove only).
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// The text of a panic's payload.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    match (payload.downcast_ref::<&str>(), payload.downcast_ref::<String>()) {
        (Some(s), _) => (*s).to_string(),
        (_, Some(s)) => s.clone(),
        _ => "(no message)".into(),
    }
}

/// Run `body` on the instance behind `ptr`: `fmi3Error` for a pointer that is not a
/// live instance; the body's error or panic is logged and leaves the instance
/// Terminated.
fn with(ptr: Fmi3Instance, func: &str, body: impl FnOnce(&mut Instance) -> Result<(), String>) -> Status {
    if !live().contains(&(ptr as usize)) {
        return Status::Error;
    }
    // SAFETY: `ptr` came from `Box::into_raw` in `fmi3InstantiateCoSimulation` and is
    // not freed (it is in LIVE); the importer uses an instance from one thread at a time,
    // so this is the only reference to it for the duration of the call.
    let inst = unsafe { &mut *ptr.cast::<Instance>() };
    let outcome = catch_unwind(AssertUnwindSafe(|| inst.call(func, body)));
    outcome.unwrap_or_else(|p| {
        let why = format!("internal error (panic): {}", panic_text(p.as_ref()));
        catch_unwind(AssertUnwindSafe(|| inst.fail(func, &why))).unwrap_or(Status::Error)
    })
}

/// A function this FMU does not support: logged, `fmi3Error`.
fn unsupported(ptr: Fmi3Instance, func: &str, why: &str) -> Status {
    with(ptr, func, |_| Err(format!("not supported: {why}")))
}

/// `n` elements at `ptr`, read-only.
///
/// # Safety
/// A non-NULL `ptr` points to `n` initialised, aligned elements that outlive `'a`.
unsafe fn slice<'a, T>(ptr: *const T, n: usize, what: &str) -> Result<&'a [T], String> {
    match (n, ptr.is_null()) {
        (0, _) => Ok(&[]),
        (_, true) => Err(format!("{what} is NULL, but its length is {n}")),
        // SAFETY: the caller's contract (the importer's arrays, FMI).
        (_, false) => Ok(unsafe { std::slice::from_raw_parts(ptr, n) }),
    }
}

/// `n` elements at `ptr`, writable.
///
/// # Safety
/// A non-NULL `ptr` points to `n` aligned elements, writable and not otherwise
/// referenced while `'a` lasts.
unsafe fn slice_mut<'a, T>(ptr: *mut T, n: usize, what: &str) -> Result<&'a mut [T], String> {
    match (n, ptr.is_null()) {
        (0, _) => Ok(&mut []),
        (_, true) => Err(format!("{what} is NULL, but its length is {n}")),
        // SAFETY: the caller's contract (the importer's arrays, FMI).
        (_, false) => Ok(unsafe { std::slice::from_raw_parts_mut(ptr, n) }),
    }
}

/// A NUL-terminated UTF-8 string.
///
/// # Safety
/// A non-NULL `p` points to a NUL-terminated string that outlives `'a`.
unsafe fn text<'a>(p: *const c_char, what: &str) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the caller's contract (FMI strings are NUL-terminated).
    let s = unsafe { CStr::from_ptr(p) };
    s.to_str().map_err(|_| format!("{what} is not UTF-8"))
}

/// Write `v` to an output argument.
///
/// # Safety
/// A non-NULL `p` is valid for writing a `T`.
unsafe fn put<T>(p: *mut T, v: T, what: &str) -> Result<(), String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: the caller's contract (an output argument of the importer's).
    unsafe { p.write(v) };
    Ok(())
}

/// The importer's log callback as a Rust closure.
fn sink(callback: LogMessageCallback, env: Fmi3InstanceEnvironment) -> Option<LogFn> {
    let cb = callback?;
    Some(Box::new(move |status: Status, category: &str, message: &str| {
        let category = CString::new(category).unwrap_or_default();
        let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
        // SAFETY: the importer's own callback with its own environment pointer and two
        // NUL-terminated strings that live until it returns.
        unsafe { cb(env, status, category.as_ptr(), message.as_ptr()) }
    }))
}

// ---------------------------------------------------------------------------------
// Common functions
// ---------------------------------------------------------------------------------

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: Fmi3Instance,
    loggingOn: Fmi3Boolean,
    nCategories: usize,
    categories: *const Fmi3String,
) -> Status {
    with(instance, "fmi3SetDebugLogging", |inst| {
        // SAFETY: the importer's array of nCategories strings.
        let ptrs = unsafe { slice(categories, nCategories, "categories")? };
        let names = ptrs
            .iter()
            .enumerate()
            // SAFETY: each element is a NUL-terminated string (FMI).
            .map(|(i, p)| unsafe { text(*p, &format!("categories[{i}]")) })
            .collect::<Result<Vec<&str>, String>>()?;
        inst.set_debug_logging(loggingOn, &names)
    })
}

/// Log an instantiation failure through the importer's callback (there is no instance).
fn refuse(callback: LogMessageCallback, env: Fmi3InstanceEnvironment, func: &str, why: &str) -> Fmi3Instance {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        Logger::new(sink(callback, env), true).error(&format!("{func}: {why}"));
    }));
    std::ptr::null_mut()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    _instanceName: Fmi3String,
    _instantiationToken: Fmi3String,
    _resourcePath: Fmi3String,
    _visible: Fmi3Boolean,
    _loggingOn: Fmi3Boolean,
    instanceEnvironment: Fmi3InstanceEnvironment,
    logMessage: LogMessageCallback,
) -> Fmi3Instance {
    refuse(
        logMessage,
        instanceEnvironment,
        "fmi3InstantiateModelExchange",
        "not supported: this FMU is Co-Simulation only; the twin is a fixed-step discrete-time model \
         with its own exact discretization (the 2 kHz flange mode), not equations for an importer's integrator",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: Fmi3String,
    instantiationToken: Fmi3String,
    resourcePath: Fmi3String,
    _visible: Fmi3Boolean,
    loggingOn: Fmi3Boolean,
    _eventModeUsed: Fmi3Boolean,
    _earlyReturnAllowed: Fmi3Boolean,
    _requiredIntermediateVariables: *const Fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: Fmi3InstanceEnvironment,
    logMessage: LogMessageCallback,
    _intermediateUpdate: IntermediateUpdateCallback,
) -> Fmi3Instance {
    let func = "fmi3InstantiateCoSimulation";
    let made = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: NUL-terminated strings from the importer (FMI).
        let (name, token) =
            unsafe { (text(instanceName, "instanceName")?, text(instantiationToken, "instantiationToken")?) };
        if resourcePath.is_null() {
            return Err(
                "resourcePath is NULL: this FMU reads its settings from its resources directory".into()
            );
        }
        // SAFETY: as above.
        let resources = unsafe { text(resourcePath, "resourcePath")? };
        if nRequiredIntermediateVariables > 0 {
            return Err("intermediate variables requested, but this FMU has no intermediate update \
                        (providesIntermediateUpdate = false)"
                .into());
        }
        let log = Logger::new(sink(logMessage, instanceEnvironment), loggingOn);
        Instance::new(name, token, Path::new(resources), log)
    }));
    match made {
        Ok(Ok(inst)) => {
            let ptr = Box::into_raw(Box::new(inst));
            live().insert(ptr as usize);
            ptr.cast()
        }
        Ok(Err(why)) => refuse(logMessage, instanceEnvironment, func, &why),
        Err(p) => refuse(
            logMessage,
            instanceEnvironment,
            func,
            &format!("internal error (panic): {}", panic_text(p.as_ref())),
        ),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    _instanceName: Fmi3String,
    _instantiationToken: Fmi3String,
    _resourcePath: Fmi3String,
    _visible: Fmi3Boolean,
    _loggingOn: Fmi3Boolean,
    instanceEnvironment: Fmi3InstanceEnvironment,
    logMessage: LogMessageCallback,
    _clockUpdate: ClockUpdateCallback,
    _lockPreemption: LockPreemptionCallback,
    _unlockPreemption: UnlockPreemptionCallback,
) -> Fmi3Instance {
    refuse(
        logMessage,
        instanceEnvironment,
        "fmi3InstantiateScheduledExecution",
        "not supported: this FMU is Co-Simulation only; the twin has no clocks or model partitions",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: Fmi3Instance) {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        let mut set = live();
        if set.remove(&(instance as usize)) {
            if set.is_empty() {
                // Free the set's node too: an importer may unload the library next,
                // and memory held only by its statics would then be lost.
                *set = BTreeSet::new();
            }
            drop(set);
            // SAFETY: the pointer came from `Box::into_raw` and was live; removed from
            // LIVE above, so no later call can reach it.
            drop(unsafe { Box::from_raw(instance.cast::<Instance>()) });
        }
    }));
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: Fmi3Instance,
    _toleranceDefined: Fmi3Boolean,
    _tolerance: f64,
    startTime: f64,
    stopTimeDefined: Fmi3Boolean,
    stopTime: f64,
) -> Status {
    with(instance, "fmi3EnterInitializationMode", |inst| {
        inst.enter_initialization(startTime, stopTimeDefined.then_some(stopTime))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: Fmi3Instance) -> Status {
    with(instance, "fmi3ExitInitializationMode", Instance::exit_initialization)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: Fmi3Instance) -> Status {
    with(instance, "fmi3Terminate", Instance::terminate)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: Fmi3Instance) -> Status {
    with(instance, "fmi3Reset", |inst| {
        inst.reset();
        Ok(())
    })
}

// ---------------------------------------------------------------------------------
// Getting and setting variable values
// ---------------------------------------------------------------------------------

/// Getters and setters of the types this FMU has variables of: each checks the
/// importer's arrays and hands them to the instance's typed accessor.
macro_rules! typed_access {
    ($($get:ident, $set:ident, $t:ty, $inst_get:ident, $inst_set:ident;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            instance: Fmi3Instance,
            valueReferences: *const Fmi3ValueReference,
            nValueReferences: usize,
            values: *mut $t,
            nValues: usize,
        ) -> Status {
            with(instance, stringify!($get), |inst| {
                // SAFETY: the importer's arrays of the given lengths (FMI).
                let (vrs, out) = unsafe {
                    (
                        slice(valueReferences, nValueReferences, "valueReferences")?,
                        slice_mut(values, nValues, "values")?,
                    )
                };
                inst.$inst_get(vrs, out)
            })
        }

        #[no_mangle]
        pub unsafe extern "C" fn $set(
            instance: Fmi3Instance,
            valueReferences: *const Fmi3ValueReference,
            nValueReferences: usize,
            values: *const $t,
            nValues: usize,
        ) -> Status {
            with(instance, stringify!($set), |inst| {
                // SAFETY: the importer's arrays of the given lengths (FMI).
                let (vrs, vals) = unsafe {
                    (slice(valueReferences, nValueReferences, "valueReferences")?, slice(values, nValues, "values")?)
                };
                inst.$inst_set(vrs, vals)
            })
        }
    )*};
}

typed_access! {
    fmi3GetFloat64, fmi3SetFloat64, f64, get_f64, set_f64;
    fmi3GetInt64, fmi3SetInt64, i64, get_i64, set_i64;
}

/// Getters and setters of the types this FMU has no variables of.
macro_rules! no_variables {
    ($($get:ident, $set:ident, $t:ty, $name:literal;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            instance: Fmi3Instance,
            valueReferences: *const Fmi3ValueReference,
            nValueReferences: usize,
            values: *mut $t,
            nValues: usize,
        ) -> Status {
            with(instance, stringify!($get), |inst| {
                // SAFETY: the importer's arrays of the given lengths (FMI).
                let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
                // SAFETY: as above; only checked, never written.
                unsafe { slice_mut(values, nValues, "values")? };
                inst.no_variables_of($name, vrs, nValues, false)
            })
        }

        #[no_mangle]
        pub unsafe extern "C" fn $set(
            instance: Fmi3Instance,
            valueReferences: *const Fmi3ValueReference,
            nValueReferences: usize,
            values: *const $t,
            nValues: usize,
        ) -> Status {
            with(instance, stringify!($set), |inst| {
                // SAFETY: the importer's arrays of the given lengths (FMI).
                let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
                // SAFETY: as above; only checked, never read.
                unsafe { slice(values, nValues, "values")? };
                inst.no_variables_of($name, vrs, nValues, true)
            })
        }
    )*};
}

no_variables! {
    fmi3GetFloat32, fmi3SetFloat32, f32, "Float32";
    fmi3GetInt8, fmi3SetInt8, i8, "Int8";
    fmi3GetUInt8, fmi3SetUInt8, u8, "UInt8";
    fmi3GetInt16, fmi3SetInt16, i16, "Int16";
    fmi3GetUInt16, fmi3SetUInt16, u16, "UInt16";
    fmi3GetInt32, fmi3SetInt32, i32, "Int32";
    fmi3GetUInt32, fmi3SetUInt32, u32, "UInt32";
    fmi3GetUInt64, fmi3SetUInt64, u64, "UInt64";
    fmi3GetBoolean, fmi3SetBoolean, Fmi3Boolean, "Boolean";
    fmi3GetString, fmi3SetString, Fmi3String, "String";
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *mut usize,
    _values: *mut Fmi3Binary,
    nValues: usize,
) -> Status {
    with(instance, "fmi3GetBinary", |inst| {
        // SAFETY: the importer's array of the given length (FMI).
        let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
        inst.no_variables_of("Binary", vrs, nValues, false)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *const usize,
    _values: *const Fmi3Binary,
    nValues: usize,
) -> Status {
    with(instance, "fmi3SetBinary", |inst| {
        // SAFETY: the importer's array of the given length (FMI).
        let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
        inst.no_variables_of("Binary", vrs, nValues, true)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetClock(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _values: *mut Fmi3Clock,
) -> Status {
    with(instance, "fmi3GetClock", |inst| {
        // SAFETY: the importer's array of the given length (FMI).
        let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
        inst.no_variables_of("Clock", vrs, vrs.len(), false)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetClock(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _values: *const Fmi3Clock,
) -> Status {
    with(instance, "fmi3SetClock", |inst| {
        // SAFETY: the importer's array of the given length (FMI).
        let vrs = unsafe { slice(valueReferences, nValueReferences, "valueReferences")? };
        inst.no_variables_of("Clock", vrs, vrs.len(), true)
    })
}

// ---------------------------------------------------------------------------------
// Co-Simulation
// ---------------------------------------------------------------------------------

#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: Fmi3Instance,
    currentCommunicationPoint: f64,
    communicationStepSize: f64,
    _noSetFMUStatePriorToCurrentPoint: Fmi3Boolean,
    eventHandlingNeeded: *mut Fmi3Boolean,
    terminateSimulation: *mut Fmi3Boolean,
    earlyReturn: *mut Fmi3Boolean,
    lastSuccessfulTime: *mut f64,
) -> Status {
    with(instance, "fmi3DoStep", |inst| {
        // SAFETY: the importer's output arguments (FMI); NULL is refused by `put`.
        unsafe {
            put(eventHandlingNeeded, false, "eventHandlingNeeded")?;
            put(terminateSimulation, false, "terminateSimulation")?;
            put(earlyReturn, false, "earlyReturn")?;
        }
        if lastSuccessfulTime.is_null() {
            return Err("lastSuccessfulTime is NULL".into());
        }
        let done = inst.do_step(currentCommunicationPoint, communicationStepSize);
        // SAFETY: checked non-NULL above; the importer's output argument.
        unsafe { put(lastSuccessfulTime, inst.time(), "lastSuccessfulTime")? };
        done
    })
}

// ---------------------------------------------------------------------------------
// What this FMU does not support: each function logs why and returns fmi3Error.
// ---------------------------------------------------------------------------------

const NO_EVENTS: &str =
    "the twin has no events (hasEventMode = false); it enters Step Mode at fmi3ExitInitializationMode";
const NO_CLOCKS: &str = "the twin has no clocks";
const NO_ME: &str = "this FMU is Co-Simulation only (no Model Exchange)";
const NO_SE: &str = "this FMU is Co-Simulation only (no Scheduled Execution)";
const NO_STATE: &str = "canGetAndSetFMUState = false: the twin's state is private to model-core";
const NO_DERIVATIVES: &str =
    "the twin is a discrete-time map without derivative code (providesDirectionalDerivatives = false)";
const NO_PER_ELEMENT: &str = "providesPerElementDependencies = false: the dependencies are in the model \
                              description's ModelStructure (no output depends on an input between steps)";
const NO_CONFIGURATION: &str =
    "the twin has no structural parameters (its step and data are fixed when packaged)";
const NO_OUTPUT_DERIVATIVES: &str =
    "maxOutputDerivativeOrder = 0: the outputs are the last fixed step's samples";

/// `fn name(instance, args...) -> fmi3Status` that refuses with `why`; the arguments
/// after the instance are the header's, unused.
macro_rules! unsupported {
    ($($name:ident($($arg:ident: $ty:ty),*) => $why:expr;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(instance: Fmi3Instance, $($arg: $ty),*) -> Status {
            unsupported(instance, stringify!($name), $why)
        }
    )*};
}

unsupported! {
    fmi3EnterEventMode() => NO_EVENTS;
    fmi3GetNumberOfVariableDependencies(_valueReference: Fmi3ValueReference, _nDependencies: *mut usize)
        => NO_PER_ELEMENT;
    fmi3GetVariableDependencies(
        _dependent: Fmi3ValueReference,
        _elementIndicesOfDependent: *mut usize,
        _independents: *mut Fmi3ValueReference,
        _elementIndicesOfIndependents: *mut usize,
        _dependencyKinds: *mut CEnum,
        _nDependencies: usize
    ) => NO_PER_ELEMENT;
    fmi3GetFMUState(_FMUState: *mut Fmi3FMUState) => NO_STATE;
    fmi3SetFMUState(_FMUState: Fmi3FMUState) => NO_STATE;
    fmi3FreeFMUState(_FMUState: *mut Fmi3FMUState) => NO_STATE;
    fmi3SerializedFMUStateSize(_FMUState: Fmi3FMUState, _size: *mut usize) => NO_STATE;
    fmi3SerializeFMUState(_FMUState: Fmi3FMUState, _serializedState: *mut u8, _size: usize) => NO_STATE;
    fmi3DeserializeFMUState(_serializedState: *const u8, _size: usize, _FMUState: *mut Fmi3FMUState) => NO_STATE;
    fmi3GetDirectionalDerivative(
        _unknowns: *const Fmi3ValueReference,
        _nUnknowns: usize,
        _knowns: *const Fmi3ValueReference,
        _nKnowns: usize,
        _seed: *const f64,
        _nSeed: usize,
        _sensitivity: *mut f64,
        _nSensitivity: usize
    ) => NO_DERIVATIVES;
    fmi3GetAdjointDerivative(
        _unknowns: *const Fmi3ValueReference,
        _nUnknowns: usize,
        _knowns: *const Fmi3ValueReference,
        _nKnowns: usize,
        _seed: *const f64,
        _nSeed: usize,
        _sensitivity: *mut f64,
        _nSensitivity: usize
    ) => NO_DERIVATIVES;
    fmi3EnterConfigurationMode() => NO_CONFIGURATION;
    fmi3ExitConfigurationMode() => NO_CONFIGURATION;
    fmi3GetIntervalDecimal(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _intervals: *mut f64,
        _qualifiers: *mut CEnum
    ) => NO_CLOCKS;
    fmi3GetIntervalFraction(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _counters: *mut u64,
        _resolutions: *mut u64,
        _qualifiers: *mut CEnum
    ) => NO_CLOCKS;
    fmi3GetShiftDecimal(_valueReferences: *const Fmi3ValueReference, _nValueReferences: usize, _shifts: *mut f64)
        => NO_CLOCKS;
    fmi3GetShiftFraction(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _counters: *mut u64,
        _resolutions: *mut u64
    ) => NO_CLOCKS;
    fmi3SetIntervalDecimal(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _intervals: *const f64
    ) => NO_CLOCKS;
    fmi3SetIntervalFraction(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _counters: *const u64,
        _resolutions: *const u64
    ) => NO_CLOCKS;
    fmi3SetShiftDecimal(_valueReferences: *const Fmi3ValueReference, _nValueReferences: usize, _shifts: *const f64)
        => NO_CLOCKS;
    fmi3SetShiftFraction(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _counters: *const u64,
        _resolutions: *const u64
    ) => NO_CLOCKS;
    fmi3EvaluateDiscreteStates() => NO_EVENTS;
    fmi3UpdateDiscreteStates(
        _discreteStatesNeedUpdate: *mut Fmi3Boolean,
        _terminateSimulation: *mut Fmi3Boolean,
        _nominalsOfContinuousStatesChanged: *mut Fmi3Boolean,
        _valuesOfContinuousStatesChanged: *mut Fmi3Boolean,
        _nextEventTimeDefined: *mut Fmi3Boolean,
        _nextEventTime: *mut f64
    ) => NO_EVENTS;
    fmi3EnterContinuousTimeMode() => NO_ME;
    fmi3CompletedIntegratorStep(
        _noSetFMUStatePriorToCurrentPoint: Fmi3Boolean,
        _enterEventMode: *mut Fmi3Boolean,
        _terminateSimulation: *mut Fmi3Boolean
    ) => NO_ME;
    fmi3SetTime(_time: f64) => NO_ME;
    fmi3SetContinuousStates(_continuousStates: *const f64, _nContinuousStates: usize) => NO_ME;
    fmi3GetContinuousStateDerivatives(_derivatives: *mut f64, _nContinuousStates: usize) => NO_ME;
    fmi3GetEventIndicators(_eventIndicators: *mut f64, _nEventIndicators: usize) => NO_ME;
    fmi3GetContinuousStates(_continuousStates: *mut f64, _nContinuousStates: usize) => NO_ME;
    fmi3GetNominalsOfContinuousStates(_nominals: *mut f64, _nContinuousStates: usize) => NO_ME;
    fmi3GetNumberOfEventIndicators(_nEventIndicators: *mut usize) => NO_ME;
    fmi3GetNumberOfContinuousStates(_nContinuousStates: *mut usize) => NO_ME;
    fmi3EnterStepMode() => NO_EVENTS;
    fmi3GetOutputDerivatives(
        _valueReferences: *const Fmi3ValueReference,
        _nValueReferences: usize,
        _orders: *const i32,
        _values: *mut f64,
        _nValues: usize
    ) => NO_OUTPUT_DERIVATIVES;
    fmi3ActivateModelPartition(_clockReference: Fmi3ValueReference, _activationTime: f64) => NO_SE;
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use super::*;
    use crate::description::token;
    use crate::instance::Mode;
    use crate::spec::{Settings, Spec, SETTINGS_FILE};

    #[test]
    fn a_panic_becomes_a_logged_error_and_the_instance_ends() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(SETTINGS_FILE), Settings::default().to_toml()).unwrap();
        let tok = token(&Spec::load(dir.path()).unwrap()).unwrap();
        let log = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink_log = log.clone();
        let sink: LogFn = Box::new(move |_, _, m: &str| sink_log.lock().unwrap().push(m.to_string()));
        let inst = Instance::new("p", &tok, dir.path(), Logger::new(Some(sink), false)).unwrap();
        let ptr = Box::into_raw(Box::new(inst));
        live().insert(ptr as usize);

        let s = with(ptr.cast(), "fmi3Test", |_| panic!("boom"));
        assert_eq!(s, Status::Error);
        assert_eq!(log.lock().unwrap().last().unwrap(), "p: fmi3Test: internal error (panic): boom");
        // SAFETY: the instance is live (in LIVE) and not used elsewhere.
        assert_eq!(unsafe { &*ptr }.mode(), Mode::Terminated);
        // SAFETY: freed once; LIVE forgets it.
        unsafe { fmi3FreeInstance(ptr.cast()) };
        assert!(!live().contains(&(ptr as usize)));
        assert_eq!(with(ptr.cast(), "fmi3Test", |_| Ok(())), Status::Error, "a freed instance is refused");
    }
}
