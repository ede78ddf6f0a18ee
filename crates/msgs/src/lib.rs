//! grip-msgs
