//! grip-arte
