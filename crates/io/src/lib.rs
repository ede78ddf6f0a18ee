//! grip-io
