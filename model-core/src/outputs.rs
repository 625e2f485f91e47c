//! Output channels: the bench's measured channels under their export names and units
//! (thesis tables 5.1, 5.5, 5.12, 5.13), the derived quantities, and internal signals.

macro_rules! channels {
    ($($var:ident => $name:literal, $unit:literal, $doc:literal;)*) => {
        /// One output channel. `Channel as usize` indexes [`Outputs::values`].
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(u8)]
        #[allow(non_camel_case_types)]
        pub enum Channel { $(#[doc = $doc] $var,)* }

        impl Channel {
            /// Every channel, in output order.
            pub const ALL: &'static [Channel] = &[$(Channel::$var,)*];
            /// Name as the bench exports it.
            pub const fn name(self) -> &'static str { match self { $(Channel::$var => $name,)* } }
            /// Unit.
            pub const fn unit(self) -> &'static str { match self { $(Channel::$var => $unit,)* } }
            /// Look up by exported name.
            pub fn from_name(name: &str) -> Option<Channel> {
                Self::ALL.iter().copied().find(|c| c.name() == name)
            }
        }
    };
}

channels! {
    Throttle => "Throttle", "V", "Throttle voltage at the controller (measured).";
    SuTMotorEnc => "SuTMotorEnc", "rpm", "SuT motor speed (measured).";
    CKistlerL => "C_Kistler_L", "N m", "Axle torque L at the torque flange (measured).";
    CKistlerR => "C_Kistler_R", "N m", "Axle torque R at the torque flange (measured).";
    TKistlerL => "T_Kistler_L", "rpm", "Axle speed L at the torque flange (measured).";
    TKistlerR => "T_Kistler_R", "rpm", "Axle speed R at the torque flange (measured).";
    SiemensEnc => "SiemensEnc", "rpm", "Load-side speed behind the R coupling (measured).";
    IXlml22 => "I_XLML 2.2", "A", "Load motor L current, probe 1 of 2 (measured; total = sum).";
    IXlmlBu1 => "I_XLML BU1", "A", "Load motor L current, probe 2 of 2 (measured).";
    IXlmr23 => "I_XLMR 2.3", "A", "Load motor R current, one of two conductors (measured; total = 2x).";
    IDpu27 => "I_DPU 2.7", "A", "Power supply current (measured).";
    VDcBusbars => "V_DC_busbars", "V", "Voltage at the busbars (measured).";
    IDc => "I_DC", "A", "SuT inverter DC current (measured).";
    VDc => "V_DC", "V", "SuT inverter DC voltage (measured).";
    PDpu => "P_DPU", "W", "Supply power, V_DC_busbars * I_DPU 2.7.";
    PSutInv => "P_SuT_inv", "W", "SuT inverter power, V_DC * I_DC.";
    PLml => "P_LML", "W", "Load motor L power, XLMLtot * V_DC_busbars.";
    PLmr => "P_LMR", "W", "Load motor R power, XLMRtot * V_DC_busbars.";
    PConn => "P_conn", "W", "Connector loss, (V_DC_busbars - V_DC) * I_DC.";
    TorqueTot => "Torque_tot", "N m", "(C_Kistler_L + C_Kistler_R) / 2.";
    TorqueDiff => "Torque_diff", "N m", "C_Kistler_L - C_Kistler_R (signed; the thesis uses its magnitude).";
    SpeedTot => "Speed_tot", "rpm", "(T_Kistler_L + T_Kistler_R) / 2.";
    SpeedDiff => "Speed_diff", "rpm", "T_Kistler_L - T_Kistler_R (signed).";
    ThrottleSp => "Throttle_sp", "%", "Throttle set point, signed (input).";
    LoadLSp => "Load_L_sp", "%", "Load L set point, + regenerating (input).";
    LoadRSp => "Load_R_sp", "%", "Load R set point, + regenerating (input).";
    ThrottleMapped => "Throttle_mapped", "%", "Mapped throttle inside the controller (internal).";
    SpeedTarget => "Speed_target", "rpm", "Target motor speed from the map (internal).";
    SpeedCmd => "Speed_cmd", "rpm", "Rate-limited speed command (internal).";
    RateCase => "Rate_case", "-", "Curtis case: 0 hold, 1 full, 2 partial, 3 low accel, 4 neutral, 5 partial decel.";
    SuTTorque => "SuT_torque", "N m", "SuT motor torque, motor frame (internal).";
    LoadTorqueL => "Load_torque_L", "N m", "Load motor L torque on the shaft, axle frame, + braking forward motion (internal).";
    LoadTorqueR => "Load_torque_R", "N m", "Load motor R torque on the shaft, axle frame (internal).";
    ILmlPhase => "I_LML_phase", "A", "Load motor L phase current from the current map (internal).";
    ILmrPhase => "I_LMR_phase", "A", "Load motor R phase current from the current map (internal).";
    LoadSpeedL => "LML_speed", "rpm", "Load motor L shaft speed (internal).";
    LoadSpeedR => "LMR_speed", "rpm", "Load motor R shaft speed (internal).";
}

/// Number of channels.
pub const N_CHANNELS: usize = Channel::ALL.len();

/// The channels the real bench measures (what a virtual-bench file contains).
pub const MEASURED: &[Channel] = &[
    Channel::Throttle,
    Channel::SuTMotorEnc,
    Channel::CKistlerL,
    Channel::CKistlerR,
    Channel::TKistlerL,
    Channel::TKistlerR,
    Channel::SiemensEnc,
    Channel::IXlml22,
    Channel::IXlmlBu1,
    Channel::IXlmr23,
    Channel::IDpu27,
    Channel::VDcBusbars,
    Channel::IDc,
    Channel::VDc,
];

/// All outputs of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outputs {
    /// [µs] time at the end of the step.
    pub t_us: u64,
    /// Channel values, indexed by `Channel as usize`.
    pub values: [f32; N_CHANNELS],
}

impl Outputs {
    /// Value of one channel.
    #[inline]
    pub fn get(&self, c: Channel) -> f32 {
        self.values.get(c as usize).copied().unwrap_or(f32::NAN)
    }

    /// The first channel (in `Channel::ALL` order) whose value is not finite: a run that
    /// diverged. Callers refuse to write such a step.
    pub fn non_finite(&self) -> Option<Channel> {
        Channel::ALL.iter().copied().find(|c| !self.get(*c).is_finite())
    }

    #[inline]
    pub(crate) fn set(&mut self, c: Channel, v: f32) {
        if let Some(s) = self.values.get_mut(c as usize) {
            *s = v;
        }
    }

    /// Time [s].
    pub fn t_s(&self) -> f64 {
        self.t_us as f64 * 1e-6
    }
}

impl Default for Outputs {
    fn default() -> Self {
        Self { t_us: 0, values: [0.0; N_CHANNELS] }
    }
}
