//! grip-config
