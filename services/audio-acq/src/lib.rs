//! grip service audio-acq: the loop, drivable from tests.
