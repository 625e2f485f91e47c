//! Profiling hooks (feature `profile-hooks`, off by default): [`Model::step`] calls a
//! probe function at each block boundary, so a profiler (the firmware's `simrod-cost`)
//! can time every block. Only calls are added, the arithmetic is untouched, so the
//! outputs keep their bits; without the feature none of this is compiled.
//!
//! [`Model::step`]: crate::Model::step

/// The block of the step that starts at a probe call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Block {
    /// Set-point conditioning, throttle chain arithmetic, Curtis rate logic.
    RateLogic,
    /// Map lookups (grid search and interpolation).
    Tables,
    /// PID, gearbox and differential.
    Controller,
    /// Friction, load torques and the exact drivetrain update, per side.
    Mechanics,
    /// Rate limiters, connector, currents.
    Electrics,
    /// The output channels.
    Outputs,
}

impl Block {
    /// Every block, in `repr` order.
    pub const ALL: [Block; 6] = [
        Block::RateLogic,
        Block::Tables,
        Block::Controller,
        Block::Mechanics,
        Block::Electrics,
        Block::Outputs,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Block::RateLogic => "rate logic",
            Block::Tables => "tables",
            Block::Controller => "controller",
            Block::Mechanics => "mechanics",
            Block::Electrics => "electrics",
            Block::Outputs => "outputs",
        }
    }
}

/// A probe: called with the block that starts now.
pub type Probe = fn(Block);

/// The default probe: does nothing.
pub(crate) fn none(_: Block) {}
