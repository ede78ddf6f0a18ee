//! grip-sim
