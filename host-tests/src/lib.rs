//! Host-side tests, and what they share with the tools: the f64 reference model (the
//! physics plant with no effects, `simrod-plant`), the firmware's real-time
//! measurements on QEMU ([`rt`]) and host timing ([`hostbench`]).

pub mod hostbench;
pub mod rt;

/// The f64 reference: `simrod_plant::reference`.
pub use simrod_plant::reference;
