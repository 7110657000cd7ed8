//! A camera that shows a deformation: the displacement in the image plane.

use super::RenderError;
use super::raster::Camera;

/// Azimuth tilt away from looking straight along the view axis, degrees:
/// enough to show depth, little enough (cos 25° = 0.91) to keep the motion
/// along the other horizontal axis visible.
pub const TILT_DEG: f64 = 25.0;

/// Elevation of the automatic camera, degrees.
pub const ELEVATION_DEG: f64 = 15.0;

/// Chooses a camera for `deformed` against `original` (same vertex count):
///
/// - the *view axis* is the world axis along which the vertices moved least
///   (smallest `Σ_i (x_i − p_i)_k²`), so the motion lies in the image plane;
///   ties (within 1e-9 of the largest sum) go to the axis of the smaller
///   bounding-box extent of the original, which shows its broad side;
/// - the *up axis* is `up` if given, else y (the convention of OBJ and PLY
///   files and of the Stanford meshes) unless y is the view axis, then the
///   remaining axis of larger extent;
/// - the camera looks along the view axis turned by [`TILT_DEG`] about the
///   up axis and raised by [`ELEVATION_DEG`].
///
/// Errors for differing vertex counts, an empty mesh, non-finite
/// coordinates, or an up axis that is not 0, 1 or 2.
pub fn auto_camera(
    original: &[[f64; 3]],
    deformed: &[[f64; 3]],
    up: Option<usize>,
) -> Result<Camera, RenderError> {
    let (moved, extent) = motion_and_extent(original, deformed)?;
    let up_given = up.is_some();
    let up = up.unwrap_or(1);
    if up > 2 {
        return Err(RenderError::Invalid {
            what: "camera",
            message: format!("up axis {up} is not 0, 1 or 2"),
        });
    }
    let largest = moved.iter().cloned().fold(0.0, f64::max);
    let order = |&a: &usize, &b: &usize| {
        let close = (moved[a] - moved[b]).abs() <= 1e-9 * largest;
        if close {
            extent[a].total_cmp(&extent[b])
        } else {
            moved[a].total_cmp(&moved[b])
        }
    };
    let candidates: Vec<usize> = (0..3).filter(|&k| !up_given || k != up).collect();
    let view = candidates.iter().copied().min_by(order).unwrap_or(0);
    let up = if up_given || view != 1 {
        up
    } else {
        let (a, b) = ((view + 1) % 3, (view + 2) % 3);
        if extent[a] >= extent[b] { a } else { b }
    };
    // Azimuth is measured from axis (up+1)%3 toward (up+2)%3.
    let azimuth = if view == (up + 1) % 3 {
        TILT_DEG
    } else {
        90.0 - TILT_DEG
    };
    Ok(Camera {
        azimuth_deg: azimuth,
        elevation_deg: ELEVATION_DEG,
        up_axis: up,
    })
}

/// Per axis: the sum of squared displacements and the bounding-box extent
/// of the original.
fn motion_and_extent(
    original: &[[f64; 3]],
    deformed: &[[f64; 3]],
) -> Result<([f64; 3], [f64; 3]), RenderError> {
    if original.len() != deformed.len() {
        return Err(RenderError::VertexCount {
            what: "deformed mesh".into(),
            got: deformed.len(),
            n: original.len(),
        });
    }
    if original.is_empty() {
        return Err(RenderError::Empty {
            mesh: 0,
            what: "vertices",
        });
    }
    let mut moved = [0.0; 3];
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (i, (p, x)) in original.iter().zip(deformed).enumerate() {
        if !p.iter().chain(x).all(|c| c.is_finite()) {
            return Err(RenderError::NonFinite { mesh: 0, vertex: i });
        }
        for k in 0..3 {
            moved[k] += (x[k] - p[k]).powi(2);
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    Ok((moved, [0, 1, 2].map(|k| hi[k] - lo[k])))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box `[0, 1] × [0, 3] × [0, 2]` (tall in y) as eight corners.
    fn corners() -> Vec<[f64; 3]> {
        let mut v = Vec::new();
        for x in [0.0, 1.0] {
            for y in [0.0, 3.0] {
                for z in [0.0, 2.0] {
                    v.push([x, y, z]);
                }
            }
        }
        v
    }

    fn moved(by: [f64; 3]) -> Vec<[f64; 3]> {
        corners()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                if i == 7 {
                    [p[0] + by[0], p[1] + by[1], p[2] + by[2]]
                } else {
                    *p
                }
            })
            .collect()
    }

    #[test]
    fn a_move_along_z_is_seen_from_x_with_y_up() {
        let c = auto_camera(&corners(), &moved([0.0, 0.0, 1.0]), None).unwrap();
        // Up y: azimuth from z toward x; x is the view axis → 90° − tilt.
        assert_eq!(c.up_axis, 1);
        assert_eq!(c.azimuth_deg, 90.0 - TILT_DEG);
        assert_eq!(c.elevation_deg, ELEVATION_DEG);
    }

    #[test]
    fn a_move_along_y_is_seen_across_the_thinner_side() {
        // x and z did not move: the tie goes to x (extent 1 < 2).
        let c = auto_camera(&corners(), &moved([0.0, 1.0, 0.0]), None).unwrap();
        assert_eq!((c.up_axis, c.azimuth_deg), (1, 90.0 - TILT_DEG));
        // A move along x: z is the least-moved axis among x, z (y is up).
        let c = auto_camera(&corners(), &moved([1.0, 0.0, 0.0]), None).unwrap();
        assert_eq!(c.up_axis, 1);
        assert!(c.azimuth_deg == TILT_DEG, "view along z = (up+1)%3");
    }

    #[test]
    fn a_move_in_the_xz_plane_is_seen_from_above_y_with_another_up() {
        let c = auto_camera(&corners(), &moved([1.0, 0.0, 1.0]), None).unwrap();
        // View along y; up = the larger remaining extent, z (2 > 1).
        assert_eq!(c.up_axis, 2);
        // Azimuth from x toward y; y is (2+2)%3 → 90° − tilt.
        assert_eq!(c.azimuth_deg, 90.0 - TILT_DEG);
        // An explicit up axis is kept.
        let c = auto_camera(&corners(), &moved([1.0, 0.0, 1.0]), Some(1)).unwrap();
        assert_eq!(c.up_axis, 1);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            auto_camera(&corners(), &corners()[..3], None),
            Err(RenderError::VertexCount { got: 3, n: 8, .. })
        ));
        assert!(auto_camera(&corners(), &corners(), Some(3)).is_err());
        assert!(auto_camera(&[], &[], None).is_err());
    }
}
