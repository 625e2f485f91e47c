//! The model's data compiled into flash by `build.rs`, and the table set built from it.

#![allow(missing_docs)]

use crate::table::{Table1, Table2};

mod generated {
    include!(concat!(env!("OUT_DIR"), "/data.rs"));
}
pub use generated::*;

/// Every lookup table of the model. Borrowed, so the host can swap in maps loaded at
/// run time (identification results) while the target uses the flash statics.
#[derive(Debug, Clone, Copy)]
pub struct Maps<'a> {
    /// Throttle voltage [V] -> mapped throttle [%] (Curtis input map, fig. 3.2).
    pub throttle_input: Table1<'a>,
    /// Mapped throttle [%] -> target motor speed [rpm], forward (fig. 5.7).
    pub speed_fwd: Table1<'a>,
    /// Mapped throttle [%] -> target motor speed magnitude [rpm], reverse.
    pub speed_rev: Table1<'a>,
    /// Axle speed [rpm] -> friction torque [N m], per side L, R (fig. 5.24/5.25).
    pub friction: [Table1<'a>; 2],
    /// (throttle %, load %) -> load axle torque [N m], + regenerating, per side.
    pub load_torque: [Table2<'a>; 2],
    /// (throttle %, load %) -> load phase current [A], + motoring, per side.
    pub load_current: [Table2<'a>; 2],
    /// (throttle %, load %) -> load electrical power [W], + drawn, per side.
    pub load_power: [Table2<'a>; 2],
    /// (throttle %, mean load %) -> SuT inverter electrical power [W], + drawn.
    pub sut_power: Table2<'a>,
}

impl Maps<'_> {
    /// The 2-D tables, in a fixed order.
    pub fn tables_2d(&self) -> [&Table2<'_>; 7] {
        [
            &self.load_torque[0],
            &self.load_torque[1],
            &self.load_current[0],
            &self.load_current[1],
            &self.load_power[0],
            &self.load_power[1],
            &self.sut_power,
        ]
    }

    /// True when every 2-D table shares the SuT power map's grids, so one location of
    /// each set point serves all lookups of a step.
    pub fn shared_2d_grid(&self) -> bool {
        self.tables_2d().iter().all(|t| t.same_grid(&self.sut_power))
    }
}

impl Maps<'static> {
    /// The maps compiled from `data/`.
    pub const fn builtin() -> Self {
        Self {
            throttle_input: Table1::from_static(&THROTTLE_INPUT_X, &THROTTLE_INPUT_Y),
            speed_fwd: Table1::from_static(&SPEED_FWD_X, &SPEED_FWD_Y),
            speed_rev: Table1::from_static(&SPEED_REV_X, &SPEED_REV_Y),
            friction: [
                Table1::from_static(&FRICTION_L_X, &FRICTION_L_Y),
                Table1::from_static(&FRICTION_R_X, &FRICTION_R_Y),
            ],
            load_torque: [
                Table2::from_static(&LOAD_TORQUE_L_X, &LOAD_TORQUE_L_Y, &LOAD_TORQUE_L_Z),
                Table2::from_static(&LOAD_TORQUE_R_X, &LOAD_TORQUE_R_Y, &LOAD_TORQUE_R_Z),
            ],
            load_current: [
                Table2::from_static(&LOAD_CURRENT_L_X, &LOAD_CURRENT_L_Y, &LOAD_CURRENT_L_Z),
                Table2::from_static(&LOAD_CURRENT_R_X, &LOAD_CURRENT_R_Y, &LOAD_CURRENT_R_Z),
            ],
            load_power: [
                Table2::from_static(&LOAD_POWER_L_X, &LOAD_POWER_L_Y, &LOAD_POWER_L_Z),
                Table2::from_static(&LOAD_POWER_R_X, &LOAD_POWER_R_Y, &LOAD_POWER_R_Z),
            ],
            sut_power: Table2::from_static(&SUT_POWER_X, &SUT_POWER_Y, &SUT_POWER_Z),
        }
    }
}
