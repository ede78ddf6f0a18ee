//! grip-tcs: the three traction controllers (MFC, SRC with fuzzy optimal
//! slip, MTTE), their observers and filters, the metrics of MODELS.md §4, and
//! the linear analysis (transfer functions, K_MFC bound, Vinnicombe nu-gap).
//! Pure: no I/O, no clock; every `step` is allocation-free.

pub mod types;

pub use types::{ControlOutput, Controller, Measurement, RoadKnowledge};
