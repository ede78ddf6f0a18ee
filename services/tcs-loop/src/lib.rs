//! grip service tcs-loop: the loop, drivable from tests.
