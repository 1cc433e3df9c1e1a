//! Measurements in the view: the geometry is `myriad_measure::measurement`'s (point, distance,
//! height, area, angle, circle, azimuth; m / ft / US ft), shared with the other tools.

pub use myriad_measure::measurement::{Kind, Measurement, Units, metres_per_unit};
