//! Correct text for bitmap figures.
//!
//! plotters 0.3.7 rasterises `ab_glyph` text with two flaws that show in
//! every PNG: glyphs lose their left side bearing and are placed at whole
//! pixels (uneven letter spacing: "pr ep ar ation"), and the baseline sits
//! about a quarter of the font size above where the anchor asks (labels
//! above their tick marks). [`GoodText`] wraps any drawing backend
//! (in practice [`plotters::prelude::BitMapBackend`]) and replaces its text
//! drawing and measuring with a careful `ab_glyph` renderer over the
//! embedded DejaVu Sans: sub-pixel pen positions, kerning, side bearings,
//! anchors on the real ascent/descent, and the four right-angle rotations.
//! Everything else is passed through unchanged. The SVG backend writes text
//! as `<text>` elements and needs no such help.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};
use lse_deform::render::text::advance;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    FontStyle,
};

/// Font family name under which DejaVu Sans is registered.
pub const FONT: &str = "sans-serif";

/// Registers DejaVu Sans (regular, bold, oblique) under [`FONT`]; idempotent
/// and cheap after the first call. The SVG files name this family, which
/// every viewer has.
pub fn register_fonts() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let faces = [
                (plotters::style::FontStyle::Normal, dejavu::sans::regular()),
                (plotters::style::FontStyle::Bold, dejavu::sans::bold()),
                (plotters::style::FontStyle::Italic, dejavu::sans::oblique()),
                (plotters::style::FontStyle::Oblique, dejavu::sans::oblique()),
            ];
            for (style, bytes) in faces {
                plotters::style::register_font(FONT, style, bytes).map_err(|_| {
                    format!(
                        "embedded DejaVu Sans ({}) is not a valid font",
                        style.as_str()
                    )
                })?;
            }
            Ok(())
        })
        .clone()
}

/// The three faces of DejaVu Sans, parsed once.
struct Faces {
    /// Regular.
    regular: FontRef<'static>,
    /// Bold.
    bold: FontRef<'static>,
    /// Oblique (for italic and oblique).
    oblique: FontRef<'static>,
}

/// The parsed faces, or why they could not be parsed.
fn faces() -> Result<&'static Faces, TextError> {
    static FACES: OnceLock<Result<Faces, String>> = OnceLock::new();
    FACES
        .get_or_init(|| {
            let parse = |bytes: &'static [u8], name: &str| {
                FontRef::try_from_slice(bytes).map_err(|e| format!("DejaVu Sans {name}: {e}"))
            };
            Ok(Faces {
                regular: parse(dejavu::sans::regular(), "regular")?,
                bold: parse(dejavu::sans::bold(), "bold")?,
                oblique: parse(dejavu::sans::oblique(), "oblique")?,
            })
        })
        .as_ref()
        .map_err(|m| TextError(m.clone()))
}

/// A font that could not be loaded (reported through the backend's
/// `FontError`).
#[derive(Debug, Clone)]
pub struct TextError(String);

impl std::fmt::Display for TextError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for TextError {}

/// A drawing backend whose text is drawn by this module (see the module
/// documentation); all other drawing goes to the wrapped backend.
pub struct GoodText<B: DrawingBackend> {
    /// The wrapped backend.
    inner: B,
}

impl<B: DrawingBackend> GoodText<B> {
    /// Wraps `inner`.
    pub fn new(inner: B) -> GoodText<B> {
        GoodText { inner }
    }
}

/// Horizontal layout of a line of text at a pixel size: advance width,
/// ascent and descent (negative), and the face to draw it with.
struct Line {
    /// The face.
    font: &'static FontRef<'static>,
    /// Scale (pixel height of ascent − descent).
    scale: PxScale,
    /// Total advance width, pixels.
    width: f32,
    /// Ascent above the baseline, pixels.
    ascent: f32,
    /// Descent below the baseline, pixels (negative).
    descent: f32,
}

/// Lays out `text` in `style`.
fn layout<S: BackendTextStyle>(text: &str, style: &S) -> Result<Line, TextError> {
    let faces = faces()?;
    let font = match style.style() {
        FontStyle::Bold => &faces.bold,
        FontStyle::Italic | FontStyle::Oblique => &faces.oblique,
        FontStyle::Normal => &faces.regular,
    };
    let scale = PxScale::from(style.size().max(1.0) as f32);
    let scaled = font.as_scaled(scale);
    Ok(Line {
        font,
        scale,
        width: advance(font, scale, text),
        ascent: scaled.ascent(),
        descent: scaled.descent(),
    })
}

/// Width in pixels of `text` in regular DejaVu Sans at `size` pixels, as
/// [`GoodText`] draws it (for layout before any backend exists).
pub fn text_width(text: &str, size: f64) -> Result<f64, TextError> {
    let faces = faces()?;
    Ok(advance(&faces.regular, PxScale::from(size.max(1.0) as f32), text) as f64)
}

impl<B: DrawingBackend> DrawingBackend for GoodText<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.inner.blit_bitmap(pos, size, src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<B::ErrorType>> {
        let line = layout(text, style).map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        Ok((
            line.width.ceil() as u32,
            (line.ascent - line.descent).ceil() as u32,
        ))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 || text.is_empty() {
            return Ok(());
        }
        let line = layout(text, style).map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        let anchor = style.anchor();
        // Text-local coordinates: x along the text, y down, origin at the
        // anchor point.
        let x0 = match anchor.h_pos {
            HPos::Left => 0.0,
            HPos::Center => -0.5 * line.width,
            HPos::Right => -line.width,
        };
        let baseline = match anchor.v_pos {
            VPos::Top => line.ascent,
            VPos::Center => 0.5 * (line.ascent + line.descent),
            VPos::Bottom => line.descent,
        };
        let transform = style.transform();
        let (w, h) = self.inner.get_size();
        let scaled = line.font.as_scaled(line.scale);
        let mut pen = x0;
        let mut previous = None;
        let mut result = Ok(());
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = previous {
                pen += scaled.kern(p, id);
            }
            previous = Some(id);
            let glyph = id.with_scale_and_position(line.scale, point(pen, baseline));
            pen += scaled.h_advance(id);
            let Some(outline) = line.font.outline_glyph(glyph) else {
                continue; // a space
            };
            let bounds = outline.px_bounds();
            let inner = &mut self.inner;
            outline.draw(|gx, gy, coverage| {
                if result.is_err() || coverage <= 0.0 {
                    return;
                }
                let lx = bounds.min.x as i32 + gx as i32;
                let ly = bounds.min.y as i32 + gy as i32;
                let (dx, dy) = transform.transform(lx, ly);
                let (x, y) = (pos.0 + dx, pos.1 + dy);
                if x >= 0 && y >= 0 && (x as u32) < w && (y as u32) < h {
                    let c = BackendColor {
                        alpha: color.alpha * coverage.min(1.0) as f64,
                        rgb: color.rgb,
                    };
                    result = inner.draw_pixel((x, y), c);
                }
            });
            if result.is_err() {
                break;
            }
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plotters::prelude::*;
    use plotters::style::text_anchor::Pos;

    /// Renders `text` centred at (100, 30) into a 200 × 60 white buffer and
    /// returns the rows and columns that received ink.
    fn ink(text: &str, anchor: Pos) -> (Vec<u32>, Vec<u32>) {
        register_fonts().unwrap();
        let (w, h) = (200u32, 60u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let root =
                GoodText::new(BitMapBackend::with_buffer(&mut buf, (w, h))).into_drawing_area();
            let style = ("sans-serif", 20.0).into_font().color(&BLACK).pos(anchor);
            root.draw_text(text, &style, (100, 30)).unwrap();
            root.present().unwrap();
        }
        let dark = |x: u32, y: u32| buf[((y * w + x) * 3) as usize] < 128;
        let rows = (0..h).filter(|&y| (0..w).any(|x| dark(x, y))).collect();
        let cols = (0..w).filter(|&x| (0..h).any(|y| dark(x, y))).collect();
        (rows, cols)
    }

    #[test]
    fn centred_text_is_centred_on_its_anchor() {
        let (rows, cols) = ink("HHHH", Pos::new(HPos::Center, VPos::Center));
        let (top, bottom) = (rows[0] as f64, *rows.last().unwrap() as f64);
        let (left, right) = (cols[0] as f64, *cols.last().unwrap() as f64);
        // Capitals span the cap height, centred within a few pixels.
        assert!(
            ((top + bottom) / 2.0 - 30.0).abs() <= 3.0,
            "rows {top}..{bottom}"
        );
        assert!(
            ((left + right) / 2.0 - 100.0).abs() <= 2.0,
            "cols {left}..{right}"
        );
        assert!(bottom - top >= 12.0, "cap height of a 20 px font");
    }

    #[test]
    fn top_left_text_starts_at_its_anchor() {
        let (rows, cols) = ink("Hx", Pos::new(HPos::Left, VPos::Top));
        assert!(rows[0] >= 30 && rows[0] <= 36, "{rows:?}");
        assert!(cols[0] >= 100 && cols[0] <= 103, "{cols:?}");
    }

    #[test]
    fn measured_width_grows_with_the_text() {
        register_fonts().unwrap();
        let mut buf = vec![0u8; 30];
        let backend = GoodText::new(BitMapBackend::with_buffer(&mut buf, (10, 1)));
        let style = TextStyle::from(("sans-serif", 20.0).into_font());
        let (w1, h1) = backend.estimate_text_size("ab", &style).unwrap();
        let (w2, _) = backend.estimate_text_size("abab", &style).unwrap();
        assert!(
            w1 > 10 && (w2 as i64 - 2 * w1 as i64).abs() <= 1,
            "{w1} {w2}"
        );
        assert!((18..=26).contains(&h1), "{h1}");
    }
}
