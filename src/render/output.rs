//! PNG output through the `png` crate (8-bit RGB, no alpha).

use std::path::Path;

use super::{RenderError, check_size};

/// Writes packed RGB bytes (`3 · width · height`, rows from the top) as a
/// PNG; the path must end in `.png` and its directory is created. Written
/// atomically ([`crate::atomic`]): on an error a previous image is left as
/// it was.
pub(crate) fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
) -> Result<(), RenderError> {
    let err = |message: String| RenderError::Output {
        path: path.to_path_buf(),
        message,
    };
    let is_png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        return Err(err("the file name must end in .png".into()));
    }
    check_size(width, height, 1)?;
    if bytes.len() != 3 * width as usize * height as usize {
        return Err(err(format!(
            "{} bytes for a {width}×{height} RGB image",
            bytes.len()
        )));
    }
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| err(format!("cannot create {}: {e}", parent.display())))?;
    }
    crate::atomic::write(path, |file| {
        let mut encoder = png::Encoder::new(file, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(bytes)?;
        writer.finish()
    })
    .map_err(|e: png::EncodingError| err(e.to_string()))
}
