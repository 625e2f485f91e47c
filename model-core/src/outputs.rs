//! Output channels: the bench's measured channels under their export names and units
//! (thesis tables 5.1, 5.5, 5.12, 5.13), the derived quantities, and internal signals.

use crate::num::Real;

macro_rules! channels {
    ($($var:ident => $name:literal, $key:literal, $unit:literal, $doc:literal;)*) => {
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
            /// Parameter name in effect files: the bench name lowercased, every run of
            /// other characters one `_` (`I_XLML 2.2` → `i_xlml_2_2`).
            pub const fn key(self) -> &'static str { match self { $(Channel::$var => $key,)* } }
            /// Unit.
            pub const fn unit(self) -> &'static str { match self { $(Channel::$var => $unit,)* } }
            /// Look up by key ([`Channel::key`]).
            pub fn from_key(key: &str) -> Option<Channel> {
                Self::ALL.iter().copied().find(|c| c.key() == key)
            }
            /// Look up by exported name.
            pub fn from_name(name: &str) -> Option<Channel> {
                Self::ALL.iter().copied().find(|c| c.name() == name)
            }
        }
    };
}

channels! {
    Throttle => "Throttle", "throttle", "V", "Throttle voltage at the controller (measured).";
    SuTMotorEnc => "SuTMotorEnc", "sutmotorenc", "rpm", "SuT motor speed (measured).";
    CKistlerL => "C_Kistler_L", "c_kistler_l", "N m", "Axle torque L at the torque flange (measured).";
    CKistlerR => "C_Kistler_R", "c_kistler_r", "N m", "Axle torque R at the torque flange (measured).";
    TKistlerL => "T_Kistler_L", "t_kistler_l", "rpm", "Axle speed L at the torque flange (measured).";
    TKistlerR => "T_Kistler_R", "t_kistler_r", "rpm", "Axle speed R at the torque flange (measured).";
    SiemensEnc => "SiemensEnc", "siemensenc", "rpm", "Load-side speed behind the R coupling (measured).";
    IXlml22 => "I_XLML 2.2", "i_xlml_2_2", "A", "Load motor L current, probe 1 of 2 (measured; total = sum).";
    IXlmlBu1 => "I_XLML BU1", "i_xlml_bu1", "A", "Load motor L current, probe 2 of 2 (measured).";
    IXlmr23 => "I_XLMR 2.3", "i_xlmr_2_3", "A", "Load motor R current, one of two conductors (measured; total = 2x).";
    IDpu27 => "I_DPU 2.7", "i_dpu_2_7", "A", "Power supply current (measured).";
    VDcBusbars => "V_DC_busbars", "v_dc_busbars", "V", "Voltage at the busbars (measured).";
    IDc => "I_DC", "i_dc", "A", "SuT inverter DC current (measured).";
    VDc => "V_DC", "v_dc", "V", "SuT inverter DC voltage (measured).";
    PDpu => "P_DPU", "p_dpu", "W", "Supply power, V_DC_busbars * I_DPU 2.7.";
    PSutInv => "P_SuT_inv", "p_sut_inv", "W", "SuT inverter power, V_DC * I_DC.";
    PLml => "P_LML", "p_lml", "W", "Load motor L power, XLMLtot * V_DC_busbars.";
    PLmr => "P_LMR", "p_lmr", "W", "Load motor R power, XLMRtot * V_DC_busbars.";
    PConn => "P_conn", "p_conn", "W", "Connector loss, (V_DC_busbars - V_DC) * I_DC.";
    TorqueTot => "Torque_tot", "torque_tot", "N m", "(C_Kistler_L + C_Kistler_R) / 2.";
    TorqueDiff => "Torque_diff", "torque_diff", "N m", "C_Kistler_L - C_Kistler_R (signed; the thesis uses its magnitude).";
    SpeedTot => "Speed_tot", "speed_tot", "rpm", "(T_Kistler_L + T_Kistler_R) / 2.";
    SpeedDiff => "Speed_diff", "speed_diff", "rpm", "T_Kistler_L - T_Kistler_R (signed).";
    ThrottleSp => "Throttle_sp", "throttle_sp", "%", "Throttle set point, signed (input).";
    LoadLSp => "Load_L_sp", "load_l_sp", "%", "Load L set point, + regenerating (input).";
    LoadRSp => "Load_R_sp", "load_r_sp", "%", "Load R set point, + regenerating (input).";
    ThrottleMapped => "Throttle_mapped", "throttle_mapped", "%", "Mapped throttle inside the controller (internal).";
    SpeedTarget => "Speed_target", "speed_target", "rpm", "Target motor speed from the map (internal).";
    SpeedCmd => "Speed_cmd", "speed_cmd", "rpm", "Rate-limited speed command (internal).";
    RateCase => "Rate_case", "rate_case", "-", "Curtis case: 0 hold, 1 full, 2 partial, 3 low accel, 4 neutral, 5 partial decel.";
    SuTTorque => "SuT_torque", "sut_torque", "N m", "SuT motor torque, motor frame (internal).";
    LoadTorqueL => "Load_torque_L", "load_torque_l", "N m", "Load motor L torque on the shaft, axle frame, + braking forward motion (internal).";
    LoadTorqueR => "Load_torque_R", "load_torque_r", "N m", "Load motor R torque on the shaft, axle frame (internal).";
    ILmlPhase => "I_LML_phase", "i_lml_phase", "A", "Load motor L phase current from the current map (internal).";
    ILmrPhase => "I_LMR_phase", "i_lmr_phase", "A", "Load motor R phase current from the current map (internal).";
    LoadSpeedL => "LML_speed", "lml_speed", "rpm", "Load motor L shaft speed (internal).";
    LoadSpeedR => "LMR_speed", "lmr_speed", "rpm", "Load motor R shaft speed (internal).";
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
pub struct Outputs<R = f32> {
    /// [µs] time at the end of the step.
    pub t_us: u64,
    /// Channel values, indexed by `Channel as usize`.
    pub values: [R; N_CHANNELS],
}

impl<R: Real> Outputs<R> {
    /// All channels 0 at time 0 (for f32 the same as `default()`).
    pub fn zero() -> Self {
        Self { t_us: 0, values: [R::ZERO; N_CHANNELS] }
    }

    /// Every channel as f32 ([`Real::to_f32`]: the values themselves for the f32 twin,
    /// rounded to the nearest f32 for the fixed-point twin).
    pub fn to_f32(&self) -> Outputs<f32> {
        Outputs { t_us: self.t_us, values: self.values.map(Real::to_f32) }
    }

    /// Value of one channel.
    #[inline]
    pub fn get(&self, c: Channel) -> R {
        self.values.get(c as usize).copied().unwrap_or(R::lit(f32::NAN))
    }

    /// The first channel (in `Channel::ALL` order) whose value is not finite: a run that
    /// diverged. Callers refuse to write such a step.
    pub fn non_finite(&self) -> Option<Channel> {
        Channel::ALL.iter().copied().find(|c| !self.get(*c).is_finite())
    }

    #[inline]
    pub(crate) fn set(&mut self, c: Channel, v: R) {
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
        Self::zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A key is the bench name lowercased, every run of other characters one `_`,
    /// trimmed: what users type in effect files, so it must follow the rule exactly.
    #[test]
    fn keys_follow_the_naming_rule_and_are_unique() {
        for c in Channel::ALL {
            let mut want = std::string::String::new();
            let mut gap = false;
            for ch in c.name().chars() {
                if ch.is_ascii_alphanumeric() {
                    if gap && !want.is_empty() {
                        want.push('_');
                    }
                    gap = false;
                    want.push(ch.to_ascii_lowercase());
                } else {
                    gap = true;
                }
            }
            assert_eq!(c.key(), want, "{}", c.name());
            assert_eq!(Channel::ALL.iter().filter(|k| k.key() == c.key()).count(), 1);
        }
    }
}
