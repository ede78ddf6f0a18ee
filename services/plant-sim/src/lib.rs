//! grip service plant-sim: the loop, drivable from tests.
