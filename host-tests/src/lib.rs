//! Host-side tests, and what they share with the tools: the f64 reference model, the
//! firmware's real-time measurements on QEMU ([`rt`]) and host timing ([`hostbench`]).

pub mod hostbench;
pub mod reference;
pub mod rt;
