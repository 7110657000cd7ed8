//! Figures of several renders: panels side by side with one shared
//! framing, a caption under each and an optional title above.

use std::path::Path;

use super::raster::{Camera, Image, RenderMesh, Style, View, check_mesh, render, renumber};
use super::text::{HAlign, draw_text};
use super::{RenderError, check_size};

/// Text colour.
const BLACK: [u8; 3] = [0, 0, 0];

/// A panel of a side-by-side figure: a mesh and its caption.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel<'a> {
    /// The mesh.
    pub mesh: RenderMesh<'a>,
    /// Caption under the render (may be empty).
    pub caption: String,
}

/// Layout of a side-by-side figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Size of each panel's render, pixels.
    pub panel_width: u32,
    /// Height of each panel's render, pixels.
    pub panel_height: u32,
    /// Camera shared by all panels.
    pub camera: Camera,
    /// Free margin around the framed meshes (fraction of the smaller side).
    pub margin: f64,
    /// Title above all panels, if any.
    pub title: Option<String>,
}

impl Default for Layout {
    /// 600 × 600 panels, default camera, 6 % margin, no title.
    fn default() -> Layout {
        Layout {
            panel_width: 600,
            panel_height: 600,
            camera: Camera::default(),
            margin: 0.06,
            title: None,
        }
    }
}

/// Renders every panel with one framing (the bounding rectangle of all
/// panels' meshes seen from `layout.camera`) and writes them side by side,
/// captions underneath, to the PNG `path`. Returns the shared view.
pub fn render_side_by_side(
    panels: &[Panel<'_>],
    layout: &Layout,
    style: &Style,
    path: &Path,
) -> Result<View, RenderError> {
    if panels.is_empty() {
        return Err(RenderError::NoPanels);
    }
    for (i, p) in panels.iter().enumerate() {
        check_mesh(i, &p.mesh)?;
    }
    let sets: Vec<&[[f64; 3]]> = panels.iter().map(|p| p.mesh.positions).collect();
    let view = View::fit(
        &layout.camera,
        &sets,
        layout.panel_width,
        layout.panel_height,
        layout.margin,
    )?;
    let mut images = Vec::with_capacity(panels.len());
    for (i, p) in panels.iter().enumerate() {
        let image = render(&p.mesh, &view, style).map_err(|e| renumber(e, i))?;
        images.push((image, p.caption.clone()));
    }
    compose(&images, layout.title.as_deref(), style.background, path)?;
    Ok(view)
}

/// Writes `images` side by side (top-aligned), each with its caption
/// centred underneath, and an optional title above, to the PNG `path`.
pub fn compose(
    images: &[(Image, String)],
    title: Option<&str>,
    background: [u8; 3],
    path: &Path,
) -> Result<(), RenderError> {
    if images.is_empty() {
        return Err(RenderError::NoPanels);
    }
    const CAPTION_SIZE: f64 = 22.0;
    const TITLE_SIZE: f64 = 26.0;
    const GAP: u32 = 10;
    let any_caption = images.iter().any(|(_, c)| !c.is_empty());
    let caption_h = if any_caption { 44 } else { 0 };
    let title_h = if title.is_some_and(|t| !t.is_empty()) {
        48
    } else {
        0
    };
    let total_w: u32 =
        images.iter().map(|(i, _)| i.width).sum::<u32>() + GAP * (images.len() as u32 + 1);
    let max_h = images.iter().map(|(i, _)| i.height).max().unwrap_or(0);
    let total_h = title_h + max_h + caption_h + GAP;
    check_size(total_w, total_h, 1)?;
    let mut canvas = Image::filled(total_w, total_h, background);
    let mut x0 = GAP;
    let mut centres = Vec::with_capacity(images.len());
    for (image, _) in images {
        for y in 0..image.height {
            let src = &image.pixels[(y * image.width) as usize..((y + 1) * image.width) as usize];
            let start = ((title_h + y) * total_w + x0) as usize;
            canvas.pixels[start..start + image.width as usize].copy_from_slice(src);
        }
        centres.push(x0 + image.width / 2);
        x0 += image.width + GAP;
    }
    if let Some(t) = title.filter(|t| !t.is_empty()) {
        let at = (0.5 * total_w as f64, 0.5 * title_h as f64);
        draw_text(&mut canvas, t, TITLE_SIZE, at, HAlign::Centre, BLACK)?;
    }
    for ((_, caption), cx) in images.iter().zip(&centres) {
        let at = (
            *cx as f64,
            (title_h + max_h) as f64 + 0.5 * caption_h as f64,
        );
        draw_text(
            &mut canvas,
            caption,
            CAPTION_SIZE,
            at,
            HAlign::Centre,
            BLACK,
        )?;
    }
    canvas.save_png(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate;
    use crate::render::Edges;

    fn plain() -> Style {
        Style {
            supersample: 1,
            edges: Edges::Off,
            ..Style::default()
        }
    }

    #[test]
    fn no_panels_is_an_error() {
        assert!(matches!(
            render_side_by_side(&[], &Layout::default(), &plain(), Path::new("x.png")),
            Err(RenderError::NoPanels)
        ));
    }

    #[test]
    fn side_by_side_writes_a_png_of_the_composed_size() {
        let dir = std::env::temp_dir().join(format!("lse-render-test-{}", std::process::id()));
        let grid = generate::grid(3, 3).unwrap();
        let lifted: Vec<[f64; 3]> = grid
            .positions()
            .iter()
            .map(|p| [p[0], p[1], p[0] * p[1]])
            .collect();
        let panels = [
            Panel {
                mesh: RenderMesh::from_mesh(&grid),
                caption: "original".into(),
            },
            Panel {
                mesh: RenderMesh::new(&lifted, grid.faces()),
                caption: "deformed".into(),
            },
        ];
        let layout = Layout {
            panel_width: 120,
            panel_height: 100,
            title: Some("t".into()),
            ..Layout::default()
        };
        let path = dir.join("pair.png");
        render_side_by_side(&panels, &layout, &plain(), &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        // IHDR: width and height, big endian, at bytes 16..24.
        let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        assert_eq!((w, h), (2 * 120 + 3 * 10, 48 + 100 + 44 + 10));
        assert!(matches!(
            Image::filled(2, 2, [0; 3]).save_png(&dir.join("x.jpg")),
            Err(RenderError::Output { .. })
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
