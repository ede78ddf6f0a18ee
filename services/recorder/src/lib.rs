//! grip service recorder: the loop, drivable from tests.
