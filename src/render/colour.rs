//! Colour maps for per-vertex scalars (displacement, difference between
//! two deformations) and the legend strip that explains them.

use super::RenderError;
use super::raster::Image;
use super::text::{HAlign, draw_text, text_width};

/// Viridis (matplotlib's perceptually uniform sequential map), sampled at
/// nine evenly spaced points and interpolated linearly in sRGB.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

/// The viridis colour at `t ∈ [0, 1]` (clamped; NaN maps to 0).
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round() as u8)
}

/// A linear map from `[min, max]` to viridis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourScale {
    /// Value at the dark end.
    pub min: f64,
    /// Value at the bright end (`max ≥ min`).
    pub max: f64,
}

impl ColourScale {
    /// The scale `[0, max v]` for non-negative magnitudes `values` (a
    /// legend that starts at zero reads as "how far"). Errors for an empty
    /// list or a negative or non-finite value.
    pub fn from_zero(values: &[f64]) -> Result<ColourScale, RenderError> {
        let mut max = 0.0f64;
        for (i, &v) in values.iter().enumerate() {
            if !(v.is_finite() && v >= 0.0) {
                return Err(RenderError::Invalid {
                    what: "colour values",
                    message: format!("value {i} is {v}, not a finite magnitude"),
                });
            }
            max = max.max(v);
        }
        if values.is_empty() {
            return Err(RenderError::Invalid {
                what: "colour values",
                message: "no values".into(),
            });
        }
        Ok(ColourScale { min: 0.0, max })
    }

    /// The colour of `v` (values outside the range are clamped; a range of
    /// zero width maps everything to the dark end).
    pub fn colour(&self, v: f64) -> [u8; 3] {
        let width = self.max - self.min;
        viridis(if width > 0.0 {
            (v - self.min) / width
        } else {
            0.0
        })
    }

    /// The colours of `values`.
    pub fn colours(&self, values: &[f64]) -> Vec<[u8; 3]> {
        values.iter().map(|&v| self.colour(v)).collect()
    }
}

/// Euclidean distances `|a_i − b_i|` of corresponding vertices; errors if
/// the counts differ (`what` names `b` in the message).
pub fn distances(a: &[[f64; 3]], b: &[[f64; 3]], what: &str) -> Result<Vec<f64>, RenderError> {
    if a.len() != b.len() {
        return Err(RenderError::VertexCount {
            what: what.to_string(),
            got: b.len(),
            n: a.len(),
        });
    }
    Ok(a.iter()
        .zip(b)
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .collect())
}

/// A number for a legend: three significant digits, exponent form outside
/// `[0.01, 1000)`.
pub(crate) fn format_value(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (0.01..1000.0).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.2e}")
    }
}

/// What a legend strip shows: a colour bar with its label, and named
/// colour swatches (constraint groups).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Legend {
    /// The colour scale and what it measures (with unit), if any.
    pub scale: Option<(ColourScale, String)>,
    /// Named colours.
    pub swatches: Vec<(String, [u8; 3])>,
}

/// Height of the legend strip, pixels.
pub const LEGEND_HEIGHT: u32 = 64;

/// Text size in the legend, pixels.
const LEGEND_TEXT: f64 = 15.0;

impl Legend {
    /// Whether there is nothing to show.
    pub fn is_empty(&self) -> bool {
        self.scale.is_none() && self.swatches.is_empty()
    }

    /// Draws the legend into the bottom [`LEGEND_HEIGHT`] rows of `image`
    /// (which must be at least that tall and 200 pixels wide): the colour
    /// bar over the left half with the label above it (left-aligned) and the range ends
    /// below, the swatches in a row to the right of it.
    pub fn draw(&self, image: &mut Image) -> Result<(), RenderError> {
        if image.width < 200 || image.height < LEGEND_HEIGHT {
            return Err(RenderError::BadSize {
                width: image.width,
                height: image.height,
                supersample: 1,
            });
        }
        let top = (image.height - LEGEND_HEIGHT) as f64;
        let w = image.width as f64;
        let mut x = 0.04 * w;
        if let Some((scale, label)) = &self.scale {
            let (x0, x1) = (x, 0.5 * w);
            // Shrunk to fit the width left of the image's right margin.
            let fits = (0.92 * w / text_width(label, LEGEND_TEXT)?).min(1.0);
            draw_text(
                image,
                label,
                LEGEND_TEXT * fits,
                (x0, top + 12.0),
                HAlign::Left,
                [0; 3],
            )?;
            fill(image, (x0, top + 22.0), (x1, top + 38.0), |fx| {
                scale.colour(scale.min + fx * (scale.max - scale.min))
            });
            let y = top + 51.0;
            draw_text(
                image,
                &format_value(scale.min),
                LEGEND_TEXT,
                (x0, y),
                HAlign::Left,
                [0; 3],
            )?;
            draw_text(
                image,
                &format_value(scale.max),
                LEGEND_TEXT,
                (x1, y),
                HAlign::Right,
                [0; 3],
            )?;
            x = x1 + 0.04 * w;
        }
        for (name, colour) in &self.swatches {
            let y = top + 0.5 * LEGEND_HEIGHT as f64;
            fill(image, (x, y - 7.0), (x + 14.0, y + 7.0), |_| *colour);
            draw_text(
                image,
                name,
                LEGEND_TEXT,
                (x + 20.0, y),
                HAlign::Left,
                [0; 3],
            )?;
            x += 20.0 + text_width(name, LEGEND_TEXT)? + 18.0;
        }
        Ok(())
    }
}

/// Fills the pixel rectangle `[a, b)` (clipped to the image) with
/// `colour(fx)`, `fx ∈ [0, 1]` the horizontal position in the rectangle.
fn fill(image: &mut Image, a: (f64, f64), b: (f64, f64), colour: impl Fn(f64) -> [u8; 3]) {
    let clip = |v: f64, n: u32| (v.round().max(0.0) as u32).min(n);
    let (x0, x1) = (clip(a.0, image.width), clip(b.0, image.width));
    let (y0, y1) = (clip(a.1, image.height), clip(b.1, image.height));
    let span = (x1.saturating_sub(x0).max(2) - 1) as f64;
    for x in x0..x1 {
        let c = colour((x - x0) as f64 / span);
        for y in y0..y1 {
            image.pixels[(y * image.width + x) as usize] = c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_spans_zero_to_the_largest_distance_and_maps_its_ends() {
        // Hand-made: displacements 0, 3-4-5 triangle (5) and 2.
        let a = [[0.0; 3], [0.0; 3], [1.0, 1.0, 1.0]];
        let b = [[0.0; 3], [3.0, 4.0, 0.0], [1.0, 1.0, 3.0]];
        let d = distances(&a, &b, "deformed").unwrap();
        assert_eq!(d, vec![0.0, 5.0, 2.0]);
        let scale = ColourScale::from_zero(&d).unwrap();
        assert_eq!((scale.min, scale.max), (0.0, 5.0));
        assert_eq!(scale.colour(0.0), VIRIDIS[0]);
        assert_eq!(scale.colour(5.0), VIRIDIS[8]);
        assert_eq!(scale.colour(2.5), VIRIDIS[4]);
        assert_eq!(scale.colour(99.0), VIRIDIS[8], "clamped");
        assert!(matches!(
            distances(&a, &b[..2], "deformed"),
            Err(RenderError::VertexCount { got: 2, n: 3, .. })
        ));
        assert!(ColourScale::from_zero(&[1.0, f64::NAN]).is_err());
        assert!(ColourScale::from_zero(&[]).is_err());
    }

    #[test]
    fn the_legend_bar_runs_from_the_dark_to_the_bright_end() {
        let mut image = Image::filled(400, 100, [255; 3]);
        let legend = Legend {
            scale: Some((ColourScale { min: 0.0, max: 2.0 }, "displacement".into())),
            swatches: vec![("handle".into(), [255, 0, 0])],
        };
        legend.draw(&mut image).unwrap();
        // The bar spans x ∈ [16, 200) at rows 36 + 22 .. 36 + 38.
        let y = 100 - LEGEND_HEIGHT + 30;
        assert_eq!(image.get(16, y).unwrap(), VIRIDIS[0]);
        assert_eq!(image.get(199, y).unwrap(), VIRIDIS[8]);
        assert!(image.pixels.contains(&[255, 0, 0]), "the swatch");
        // Nothing above the strip.
        assert!((0..36 * 400).all(|i| image.pixels[i] == [255; 3]));
        assert_eq!(format_value(0.012345), "0.0123");
        assert_eq!(format_value(5.0), "5.00");
        assert_eq!(format_value(1e-5), "1.00e-5");
    }
}
