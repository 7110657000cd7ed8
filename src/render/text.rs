//! Text on rendered images: one line of DejaVu Sans (embedded), laid out
//! with `ab_glyph` at sub-pixel pen positions with kerning and side
//! bearings, anchored on the font's real ascent and descent.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};

use super::RenderError;
use super::raster::Image;

/// Horizontal anchor of a line of text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HAlign {
    /// The anchor is the left end.
    Left,
    /// The anchor is the middle.
    Centre,
    /// The anchor is the right end.
    Right,
}

/// DejaVu Sans (regular), parsed once.
pub(crate) fn font() -> Result<&'static FontRef<'static>, RenderError> {
    static FONT: OnceLock<Result<FontRef<'static>, String>> = OnceLock::new();
    FONT.get_or_init(|| {
        FontRef::try_from_slice(dejavu::sans::regular()).map_err(|e| format!("DejaVu Sans: {e}"))
    })
    .as_ref()
    .map_err(|m| RenderError::Font(m.clone()))
}

/// Total advance of `text` (advances plus kerning) in `font` at `scale`,
/// pixels.
pub fn advance(font: &FontRef<'static>, scale: PxScale, text: &str) -> f32 {
    let scaled = font.as_scaled(scale);
    let mut width = 0.0;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            width += scaled.kern(p, id);
        }
        width += scaled.h_advance(id);
        previous = Some(id);
    }
    width
}

/// Width in pixels of `text` at `size` pixels.
pub fn text_width(text: &str, size: f64) -> Result<f64, RenderError> {
    Ok(advance(font()?, PxScale::from(size.max(1.0) as f32), text) as f64)
}

/// Calls `ink(x, y, coverage)` for every pixel of `text` in `font` at
/// `scale` with the pen starting at `x0` on the baseline `y = baseline`
/// (text-local coordinates, y down).
pub(crate) fn glyph_coverage(
    font: &'static FontRef<'static>,
    scale: PxScale,
    text: &str,
    x0: f32,
    baseline: f32,
    mut ink: impl FnMut(i32, i32, f32),
) {
    let scaled = font.as_scaled(scale);
    let mut pen = x0;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            pen += scaled.kern(p, id);
        }
        previous = Some(id);
        let glyph = id.with_scale_and_position(scale, point(pen, baseline));
        pen += scaled.h_advance(id);
        let Some(outline) = font.outline_glyph(glyph) else {
            continue; // a space
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            if coverage > 0.0 {
                ink(
                    bounds.min.x as i32 + gx as i32,
                    bounds.min.y as i32 + gy as i32,
                    coverage.min(1.0),
                );
            }
        });
    }
}

/// Draws one line of `text` at `size` pixels in `colour` into `image`,
/// vertically centred on `y` and anchored horizontally at `x` by `align`.
/// Pixels outside the image are dropped.
pub(crate) fn draw_text(
    image: &mut Image,
    text: &str,
    size: f64,
    (x, y): (f64, f64),
    align: HAlign,
    colour: [u8; 3],
) -> Result<(), RenderError> {
    let font = font()?;
    let scale = PxScale::from(size.max(1.0) as f32);
    let width = advance(font, scale, text);
    let scaled = font.as_scaled(scale);
    let x0 = match align {
        HAlign::Left => 0.0,
        HAlign::Centre => -0.5 * width,
        HAlign::Right => -width,
    };
    let baseline = 0.5 * (scaled.ascent() + scaled.descent());
    let (ox, oy) = (x.round() as i32, y.round() as i32);
    let (w, h) = (image.width as i32, image.height as i32);
    glyph_coverage(font, scale, text, x0, baseline, |gx, gy, a| {
        let (px, py) = (ox + gx, oy + gy);
        if (0..w).contains(&px) && (0..h).contains(&py) {
            let p = &mut image.pixels[(py * w + px) as usize];
            for k in 0..3 {
                p[k] = (p[k] as f32 + a * (colour[k] as f32 - p[k] as f32)).round() as u8;
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centred_text_is_centred_and_its_width_grows_with_the_text() {
        let mut image = Image::filled(200, 60, [255; 3]);
        draw_text(
            &mut image,
            "HHHH",
            20.0,
            (100.0, 30.0),
            HAlign::Centre,
            [0; 3],
        )
        .unwrap();
        let dark = |x: u32, y: u32| image.get(x, y).unwrap()[0] < 128;
        let rows: Vec<u32> = (0..60).filter(|&y| (0..200).any(|x| dark(x, y))).collect();
        let cols: Vec<u32> = (0..200).filter(|&x| (0..60).any(|y| dark(x, y))).collect();
        let (top, bottom) = (rows[0] as f64, *rows.last().unwrap() as f64);
        let (left, right) = (cols[0] as f64, *cols.last().unwrap() as f64);
        assert!(
            ((top + bottom) / 2.0 - 30.0).abs() <= 3.0,
            "{top}..{bottom}"
        );
        assert!(
            ((left + right) / 2.0 - 100.0).abs() <= 2.0,
            "{left}..{right}"
        );
        assert!(bottom - top >= 12.0, "cap height of a 20 px font");
        let (w1, w2) = (
            text_width("ab", 20.0).unwrap(),
            text_width("abab", 20.0).unwrap(),
        );
        assert!(w1 > 10.0 && (w2 - 2.0 * w1).abs() <= 1.0, "{w1} {w2}");
    }
}
