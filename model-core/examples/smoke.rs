use model_core::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let prof = Builtin::from_name(&args[1]).unwrap();
    let ts: f32 = args[2].parse().unwrap();
    let ls: f32 = args[3].parse().unwrap();
    let dt: u32 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(1000);
    let cfg = Config { dt_us: dt, ..Config::default() };
    let sim = Simulation::new(&cfg, Profile::builtin(prof, ts, ls).unwrap(), 24.0).unwrap();
    let every = (500_000 / dt) as usize;
    for (k, o) in sim.enumerate() {
        if k % every == every - 1 {
            println!("{:6.2} thr={:6.1} ld={:6.1} tgt={:7.1} cmd={:7.1} n={:7.1} case={} Tm={:6.2} CL={:7.2} CR={:7.2} TL={:6.1} TR={:6.1} Sie={:6.1} Psut={:7.1} PL={:7.1} Idpu={:6.1} Vdc={:5.2}",
              o.t_s(), o.get(Channel::ThrottleSp), o.get(Channel::LoadLSp), o.get(Channel::SpeedTarget), o.get(Channel::SpeedCmd), o.get(Channel::SuTMotorEnc), o.get(Channel::RateCase), o.get(Channel::SuTTorque), o.get(Channel::CKistlerL), o.get(Channel::CKistlerR), o.get(Channel::TKistlerL), o.get(Channel::TKistlerR), o.get(Channel::SiemensEnc), o.get(Channel::PSutInv), o.get(Channel::PLml), o.get(Channel::IDpu27), o.get(Channel::VDc));
        }
    }
}
