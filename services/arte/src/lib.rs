//! grip service arte: the loop, drivable from tests.
