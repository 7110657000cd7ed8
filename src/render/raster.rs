//! The rasteriser: a small z-buffered, shaded software rasteriser for mesh figures: no GPU,
//! no system library.
//!
//! - Orthographic [`Camera`] given by azimuth and elevation around a world
//!   up axis; a [`View`] frames it to the bounding rectangle of one or
//!   several meshes ([`View::fit`]), so an original and its deformation can
//!   share the same framing.
//! - Per-pixel depth test; Lambert + ambient shading with smooth shading
//!   (vertex normals interpolated per pixel); back faces are shaded too, with
//!   their normals flipped (open meshes show both sides).
//! - Colours per vertex ([`Colouring`]): uniform, given, or a set of
//!   highlighted vertices (red, as the constrained regions of the paper's
//!   figures) over a neutral base; interpolated across faces.
//! - Optional thin edges, drawn per pixel from barycentric distances (exact
//!   under the depth test); [`Edges::Auto`] draws them only when triangles
//!   are large on screen.
//! - Supersampling (default 2 × 2) for smooth silhouettes.
//! - A translucent *ghost* (the original surface over a deformed one,
//!   [`render_with_ghost`]), depth-tested against the surface in front.

use std::path::Path;

use super::{RenderError, check_size};
use crate::mesh::Mesh;

/// Mean projected edge length (final-image pixels) from which
/// [`Edges::Auto`] draws edges.
pub const AUTO_EDGE_PIXELS: f64 = 20.0;

/// An orthographic camera looking at the framed meshes from the direction
/// given by azimuth and elevation around a world up axis.
///
/// With up axis `u` and the other two axes `a = (u+1) % 3`, `b = (u+2) % 3`,
/// the camera sits in direction `cos(el)·(cos(az)·e_a + sin(az)·e_b) +
/// sin(el)·e_u` from the scene, with `e_u` up on screen. For `u = y` (1): azimuth 0 and elevation 0
/// look down −z with x to the right and y up (the usual front view);
/// azimuth 90° looks from +x.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Rotation around the up axis, degrees.
    pub azimuth_deg: f64,
    /// Angle above the horizontal plane, degrees, in `(−90, 90)`.
    pub elevation_deg: f64,
    /// World up axis: 0 = x, 1 = y, 2 = z.
    pub up_axis: usize,
}

impl Default for Camera {
    /// A three-quarter view from above: azimuth 30°, elevation 20°, y up.
    fn default() -> Camera {
        Camera {
            azimuth_deg: 30.0,
            elevation_deg: 20.0,
            up_axis: 1,
        }
    }
}

impl Camera {
    /// A camera with y up.
    pub fn new(azimuth_deg: f64, elevation_deg: f64) -> Camera {
        Camera {
            azimuth_deg,
            elevation_deg,
            up_axis: 1,
        }
    }

    /// The camera looking at the scene from direction `toward` (scene to
    /// camera, any length), with world up axis `up_axis`; the inverse of
    /// the azimuth/elevation parametrisation. Errors for a zero or
    /// non-finite direction, a bad axis, or a direction along the up axis.
    pub fn from_direction(toward: [f64; 3], up_axis: usize) -> Result<Camera, RenderError> {
        let len = dot(toward, toward).sqrt();
        if up_axis > 2 || !(len.is_finite() && len > 0.0) {
            return Err(RenderError::Invalid {
                what: "camera",
                message: format!("direction {toward:?} with up axis {up_axis}"),
            });
        }
        let d = scale3(toward, 1.0 / len);
        let (a, b) = ((up_axis + 1) % 3, (up_axis + 2) % 3);
        let camera = Camera {
            azimuth_deg: d[b].atan2(d[a]).to_degrees(),
            elevation_deg: d[up_axis].clamp(-1.0, 1.0).asin().to_degrees(),
            up_axis,
        };
        camera.basis()?;
        Ok(camera)
    }

    /// The same camera with another world up axis.
    pub fn with_up_axis(mut self, axis: usize) -> Camera {
        self.up_axis = axis;
        self
    }

    /// Orthonormal screen basis `(right, up, toward the camera)`.
    fn basis(&self) -> Result<[[f64; 3]; 3], RenderError> {
        if self.up_axis > 2 {
            return Err(RenderError::Invalid {
                what: "camera",
                message: format!("up axis {} is not 0, 1 or 2", self.up_axis),
            });
        }
        if !(self.azimuth_deg.is_finite()
            && self.elevation_deg.is_finite()
            && self.elevation_deg.abs() < 90.0)
        {
            return Err(RenderError::Invalid {
                what: "camera",
                message: format!(
                    "azimuth {} / elevation {} (elevation must be in (−90°, 90°))",
                    self.azimuth_deg, self.elevation_deg
                ),
            });
        }
        let u = self.up_axis;
        let (a, b) = ((u + 1) % 3, (u + 2) % 3);
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        let mut toward = [0.0; 3];
        toward[a] = el.cos() * az.cos();
        toward[b] = el.cos() * az.sin();
        toward[u] = el.sin();
        let mut world_up = [0.0; 3];
        world_up[u] = 1.0;
        let right = normalize(cross(world_up, toward));
        let up = cross(toward, right);
        Ok([right, up, toward])
    }
}

/// A camera framed to a region: what maps world points to pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Screen basis `(right, up, toward the camera)`.
    basis: [[f64; 3]; 3],
    /// Centre of the framed rectangle, in (right, up) coordinates.
    centre: [f64; 2],
    /// Pixels per world unit.
    scale: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl View {
    /// Frames `camera` so that every point of every set in `point_sets`
    /// fits in a `width × height` image with `margin` (a fraction of the
    /// smaller side, in `[0, 0.45]`) left free on each side. Non-finite
    /// points are ignored; with no finite point at all this is an error.
    pub fn fit(
        camera: &Camera,
        point_sets: &[&[[f64; 3]]],
        width: u32,
        height: u32,
        margin: f64,
    ) -> Result<View, RenderError> {
        check_size(width, height, 1)?;
        if !(0.0..=0.45).contains(&margin) {
            return Err(RenderError::Invalid {
                what: "margin",
                message: format!("{margin} is not in [0, 0.45]"),
            });
        }
        let basis = camera.basis()?;
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in point_sets.iter().flat_map(|s| s.iter()) {
            if !p.iter().all(|c| c.is_finite()) {
                continue;
            }
            for k in 0..2 {
                let v = dot(*p, basis[k]);
                lo[k] = lo[k].min(v);
                hi[k] = hi[k].max(v);
            }
        }
        if !(lo[0].is_finite() && hi[0].is_finite()) {
            return Err(RenderError::Invalid {
                what: "framing",
                message: "no finite point to frame".into(),
            });
        }
        let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let extent = [hi[0] - lo[0], hi[1] - lo[1]];
        let m = margin * width.min(height) as f64;
        let avail = [
            (width as f64 - 2.0 * m).max(1.0),
            (height as f64 - 2.0 * m).max(1.0),
        ];
        let scale = match (extent[0] > 0.0, extent[1] > 0.0) {
            (true, true) => (avail[0] / extent[0]).min(avail[1] / extent[1]),
            (true, false) => avail[0] / extent[0],
            (false, true) => avail[1] / extent[1],
            (false, false) => 1.0,
        };
        Ok(View {
            basis,
            centre,
            scale,
            width,
            height,
        })
    }

    /// The pixel position `(x, y)` (x right, y down, pixel centres at
    /// half-integers) and depth (larger is nearer) of a world point.
    pub(crate) fn project(&self, p: [f64; 3]) -> [f64; 3] {
        [
            (dot(p, self.basis[0]) - self.centre[0]) * self.scale + 0.5 * self.width as f64,
            0.5 * self.height as f64 - (dot(p, self.basis[1]) - self.centre[1]) * self.scale,
            dot(p, self.basis[2]),
        ]
    }

    /// The same framing at `factor` times the resolution.
    pub(crate) fn scaled(&self, factor: u32) -> View {
        View {
            scale: self.scale * factor as f64,
            width: self.width * factor,
            height: self.height * factor,
            ..*self
        }
    }
}

/// How vertices are coloured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Colouring<'a> {
    /// Everything in [`Style::base`].
    #[default]
    Uniform,
    /// One sRGB colour per vertex.
    PerVertex(&'a [[u8; 3]]),
    /// These vertices in [`Style::highlight`], the rest in [`Style::base`]
    /// (duplicates allowed).
    Highlight(&'a [usize]),
}

/// A mesh to render: positions, faces and colouring (borrowed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderMesh<'a> {
    /// Vertex positions.
    pub positions: &'a [[f64; 3]],
    /// Triangles (vertex indices).
    pub faces: &'a [[usize; 3]],
    /// Vertex colours.
    pub colouring: Colouring<'a>,
}

impl<'a> RenderMesh<'a> {
    /// A uniformly coloured mesh.
    pub fn new(positions: &'a [[f64; 3]], faces: &'a [[usize; 3]]) -> RenderMesh<'a> {
        RenderMesh {
            positions,
            faces,
            colouring: Colouring::Uniform,
        }
    }

    /// A uniformly coloured [`Mesh`].
    pub fn from_mesh(mesh: &'a Mesh) -> RenderMesh<'a> {
        RenderMesh::new(mesh.positions(), mesh.faces())
    }

    /// The same mesh with the given vertices highlighted.
    pub fn highlight(mut self, vertices: &'a [usize]) -> RenderMesh<'a> {
        self.colouring = Colouring::Highlight(vertices);
        self
    }

    /// The same mesh with per-vertex colours.
    pub fn colours(mut self, colours: &'a [[u8; 3]]) -> RenderMesh<'a> {
        self.colouring = Colouring::PerVertex(colours);
        self
    }
}

/// When to draw triangle edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Edges {
    /// Never.
    Off,
    /// Always.
    On,
    /// When the mean projected edge is at least [`AUTO_EDGE_PIXELS`] long
    /// (small meshes).
    #[default]
    Auto,
}

/// Colours and shading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Neutral surface colour.
    pub base: [u8; 3],
    /// Colour of highlighted vertices.
    pub highlight: [u8; 3],
    /// Background.
    pub background: [u8; 3],
    /// Edge colour.
    pub edge_colour: [u8; 3],
    /// Ambient term, in `[0, 1]`.
    pub ambient: f64,
    /// Diffuse (Lambert) term, in `[0, 1]`; `ambient + diffuse` is the
    /// brightness of a surface facing the light.
    pub diffuse: f64,
    /// Brightness factor of back faces (inside of open meshes), in `[0, 1]`.
    pub back_factor: f64,
    /// Edge drawing.
    pub edges: Edges,
    /// Edge width, final-image pixels.
    pub edge_width: f64,
    /// Supersampling factor per axis (1 = none), in `1..=4`.
    pub supersample: u32,
}

impl Default for Style {
    /// Light grey surface, red highlights, white background, 2 × 2
    /// supersampling, edges on small meshes.
    fn default() -> Style {
        Style {
            base: [200, 200, 196],
            highlight: [215, 35, 30],
            background: [255, 255, 255],
            edge_colour: [40, 40, 40],
            ambient: 0.28,
            diffuse: 0.72,
            back_factor: 0.8,
            edges: Edges::Auto,
            edge_width: 0.8,
            supersample: 2,
        }
    }
}

/// An RGB image, row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` sRGB pixels.
    pub pixels: Vec<[u8; 3]>,
}

impl Image {
    /// A `width × height` image filled with `colour`.
    pub fn filled(width: u32, height: u32, colour: [u8; 3]) -> Image {
        Image {
            width,
            height,
            pixels: vec![colour; width as usize * height as usize],
        }
    }

    /// The pixel at `(x, y)`, `None` outside.
    pub fn get(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height)
            .then(|| self.pixels[y as usize * self.width as usize + x as usize])
    }

    /// The pixels as packed RGB bytes.
    pub fn bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }

    /// Writes the image as a PNG (the path must end in `.png`).
    pub fn save_png(&self, path: &Path) -> Result<(), RenderError> {
        super::output::write_png(path, self.width, self.height, &self.bytes())
    }
}

/// What the rasteriser did, for timing and sanity checks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderStats {
    /// Triangles rasterised (projected area non-zero, on screen).
    pub triangles_drawn: usize,
    /// Pixels (supersampled) written after the depth test.
    pub fragments_written: usize,
    /// Whether edges were drawn.
    pub edges: bool,
}

/// Renders `mesh` framed by `view` with `style`.
pub fn render(mesh: &RenderMesh<'_>, view: &View, style: &Style) -> Result<Image, RenderError> {
    render_with_stats(mesh, view, style).map(|(image, _)| image)
}

/// [`render`], also returning what was drawn.
pub(crate) fn render_with_stats(
    mesh: &RenderMesh<'_>,
    view: &View,
    style: &Style,
) -> Result<(Image, RenderStats), RenderError> {
    check_style(style)?;
    check_size(view.width, view.height, style.supersample)?;
    let (layer, stats) = rasterise(0, mesh, view, style)?;
    Ok((resolve(&layer, None, view, style), stats))
}

/// A translucent surface drawn over the image where it is nearer than the
/// opaque surface (or where there is none): the original mesh as a ghost
/// over its deformation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ghost<'a> {
    /// Positions and faces (its colouring is ignored: it is drawn in
    /// `colour`).
    pub mesh: RenderMesh<'a>,
    /// Its colour.
    pub colour: [u8; 3],
    /// Opacity in `[0, 1]`: the weight of the ghost's shaded colour over
    /// what lies behind it.
    pub opacity: f64,
}

/// Renders `mesh` opaque and `ghost` translucent over it, depth-tested
/// against each other (a ghost behind the surface is hidden).
pub fn render_with_ghost(
    mesh: &RenderMesh<'_>,
    ghost: &Ghost<'_>,
    view: &View,
    style: &Style,
) -> Result<Image, RenderError> {
    check_style(style)?;
    check_size(view.width, view.height, style.supersample)?;
    if !(0.0..=1.0).contains(&ghost.opacity) {
        return Err(RenderError::Invalid {
            what: "ghost",
            message: format!("opacity {} is not in [0, 1]", ghost.opacity),
        });
    }
    let (front, _) = rasterise(0, mesh, view, style)?;
    let ghost_style = Style {
        base: ghost.colour,
        edges: Edges::Off,
        ..*style
    };
    let plain = RenderMesh::new(ghost.mesh.positions, ghost.mesh.faces);
    let (behind, _) = rasterise(1, &plain, view, &ghost_style)?;
    Ok(resolve(
        &front,
        Some((&behind, ghost.opacity as f32)),
        view,
        style,
    ))
}

/// A supersampled raster: shaded colour, depth (larger is nearer) and
/// coverage per sample.
struct Layer {
    /// Shaded colours in `[0, 1]`.
    colour: Vec<[f32; 3]>,
    /// Depth per sample.
    depth: Vec<f32>,
    /// Whether a triangle covers the sample.
    written: Vec<bool>,
}

/// Rasterises mesh number `index` at `style.supersample` times the
/// resolution of `view` (style and size already checked): vertex colours,
/// normals and projections once, then each triangle in turn
/// ([`screen_triangle`], [`draw_triangle`]) with a depth test.
fn rasterise(
    index: usize,
    mesh: &RenderMesh<'_>,
    view: &View,
    style: &Style,
) -> Result<(Layer, RenderStats), RenderError> {
    let colours = vertex_colours(index, mesh, style)?;
    let ss = style.supersample;
    let hi = view.scaled(ss);
    let (w, h) = (hi.width as usize, hi.height as usize);
    let normals = vertex_normals(mesh.positions, mesh.faces);
    let projected: Vec<[f64; 3]> = mesh.positions.iter().map(|&p| hi.project(p)).collect();
    let edges = match style.edges {
        Edges::Off => false,
        Edges::On => true,
        Edges::Auto => mean_edge_pixels(&projected, mesh.faces) / ss as f64 >= AUTO_EDGE_PIXELS,
    };
    let [_, _, toward] = hi.basis;
    let to_f = |c: [u8; 3]| c.map(|v| v as f32 / 255.0);
    let shading = Shading {
        key: key_light(hi.basis),
        toward,
        edges,
        edge_half: 0.5 * style.edge_width * ss as f64,
        edge_colour: to_f(style.edge_colour),
    };
    let mut layer = Layer {
        colour: vec![[0.0f32; 3]; w * h],
        depth: vec![f32::NEG_INFINITY; w * h],
        written: vec![false; w * h],
    };
    let mut stats = RenderStats {
        edges,
        ..RenderStats::default()
    };
    for face in mesh.faces {
        let [i0, i1, i2] = *face;
        let corners = [projected[i0], projected[i1], projected[i2]];
        let Some((area, bounds)) = screen_triangle(corners, w, h) else {
            continue;
        };
        stats.triangles_drawn += 1;
        let face_normal = normalize(cross(
            sub3(mesh.positions[i1], mesh.positions[i0]),
            sub3(mesh.positions[i2], mesh.positions[i0]),
        ));
        let triangle = Triangle {
            corners,
            area,
            normals: [normals[i0], normals[i1], normals[i2]],
            face_normal,
            colours: [colours[i0], colours[i1], colours[i2]],
        };
        stats.fragments_written += draw_triangle(&mut layer, w, bounds, &triangle, &shading, style);
    }
    Ok((layer, stats))
}

/// The key light, in world coordinates, from the screen basis `(right, up,
/// toward the camera)`: from the upper left front. (A weaker one comes
/// from the camera, `toward`.)
fn key_light([right, up, toward]: [[f64; 3]; 3]) -> [f64; 3] {
    normalize(add3(
        add3(scale3(right, -0.4), scale3(up, 0.5)),
        scale3(toward, 0.77),
    ))
}

/// The projected triangle's signed doubled area and its pixel bounds
/// `[min_x, min_y, max_x, max_y)` clipped to the `w × h` raster, or `None`
/// when it is seen edge-on (`|area| < 1e-12`), its projection overflowed
/// (coordinates near `f64::MAX`: no pixel centre is covered reliably), or
/// it is off screen.
fn screen_triangle([a, b, c]: [[f64; 3]; 3], w: usize, h: usize) -> Option<(f64, [usize; 4])> {
    let area = edge_fn(a, b, c[0], c[1]);
    if !(area.abs() >= 1e-12 && area.is_finite()) {
        return None;
    }
    let min_x = a[0].min(b[0]).min(c[0]).floor().max(0.0) as usize;
    let min_y = a[1].min(b[1]).min(c[1]).floor().max(0.0) as usize;
    let max_x = a[0].max(b[0]).max(c[0]).ceil().min(w as f64) as usize;
    let max_y = a[1].max(b[1]).max(c[1]).ceil().min(h as f64) as usize;
    if min_x >= max_x || min_y >= max_y {
        return None;
    }
    Some((area, [min_x, min_y, max_x, max_y]))
}

/// Heights of the triangle over each edge, in pixels (edge `i` is opposite
/// vertex `i`): the distance to edge `i` is `λ_i · h_i`. Edge lengths are
/// floored at `1e-12` (a degenerate edge is not divided by).
fn edge_heights([a, b, c]: [[f64; 3]; 3], area: f64) -> [f64; 3] {
    let len = |p: [f64; 3], q: [f64; 3]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
    [
        area.abs() / len(b, c).max(1e-12),
        area.abs() / len(c, a).max(1e-12),
        area.abs() / len(a, b).max(1e-12),
    ]
}

/// What shading a sample needs besides its triangle: the lights, and the
/// wireframe (whether drawn, its half width in samples, its colour).
struct Shading {
    key: [f64; 3],
    toward: [f64; 3],
    edges: bool,
    edge_half: f64,
    edge_colour: [f32; 3],
}

/// A projected triangle with what is interpolated across it.
struct Triangle {
    /// Projected corners (screen x, y in samples; depth).
    corners: [[f64; 3]; 3],
    /// Signed doubled area on screen (`> 0`: back facing).
    area: f64,
    /// Vertex normals of the corners.
    normals: [[f64; 3]; 3],
    /// The face normal, for a sample whose interpolated normal vanishes.
    face_normal: [f64; 3],
    /// Vertex colours of the corners.
    colours: [[f32; 3]; 3],
}

/// Draws `t` into `layer` (width `w`) over the sample `bounds`: a sample
/// centre is inside when its barycentric coordinates are all `≥ 0` (NaN
/// counts as outside) and drawn when nearer than what is there (depth
/// test); returns how many were written.
fn draw_triangle(
    layer: &mut Layer,
    w: usize,
    [min_x, min_y, max_x, max_y]: [usize; 4],
    t: &Triangle,
    shading: &Shading,
    style: &Style,
) -> usize {
    let [a, b, c] = t.corners;
    // Clockwise on screen (y down) is counter-clockwise in the world
    // seen from the camera: front facing when the signed area is < 0.
    let back = t.area > 0.0;
    let inv = 1.0 / t.area;
    let heights = if shading.edges {
        edge_heights(t.corners, t.area)
    } else {
        [0.0; 3]
    };
    let mut written = 0;
    for y in min_y..max_y {
        let py = y as f64 + 0.5;
        for x in min_x..max_x {
            let px = x as f64 + 0.5;
            let l0 = edge_fn(b, c, px, py) * inv;
            let l1 = edge_fn(c, a, px, py) * inv;
            let l2 = 1.0 - l0 - l1;
            // Written so that NaN (overflow) counts as outside.
            if !(l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0) {
                continue;
            }
            let z = (l0 * a[2] + l1 * b[2] + l2 * c[2]) as f32;
            let idx = y * w + x;
            if z <= layer.depth[idx] {
                continue;
            }
            layer.depth[idx] = z;
            layer.written[idx] = true;
            written += 1;
            layer.colour[idx] = shade_sample([l0, l1, l2], back, heights, t, shading, style);
        }
    }
    written
}

/// The colour of a sample at barycentric `[l0, l1, l2]` of `t`: the
/// interpolated vertex colour times `ambient + diffuse · lambert` (`0.7`
/// of the key light, `0.3` of the camera light, on the interpolated
/// normal, the face normal when it vanishes below `1e-12`, flipped and
/// darkened by `back_factor` on a back face), capped at 1; then blended
/// towards the edge colour (at most 85 %) within `edge_half` samples of an
/// edge.
fn shade_sample(
    [l0, l1, l2]: [f64; 3],
    back: bool,
    heights: [f64; 3],
    t: &Triangle,
    shading: &Shading,
    style: &Style,
) -> [f32; 3] {
    let [n0, n1, n2] = t.normals;
    let [c0, c1, c2] = t.colours;
    let mut nrm = [
        l0 * n0[0] + l1 * n1[0] + l2 * n2[0],
        l0 * n0[1] + l1 * n1[1] + l2 * n2[1],
        l0 * n0[2] + l1 * n1[2] + l2 * n2[2],
    ];
    let len = dot(nrm, nrm).sqrt();
    nrm = if len > 1e-12 {
        scale3(nrm, 1.0 / len)
    } else {
        t.face_normal
    };
    if back {
        nrm = scale3(nrm, -1.0);
    }
    let lambert = 0.7 * dot(nrm, shading.key).max(0.0) + 0.3 * dot(nrm, shading.toward).max(0.0);
    let mut shade = style.ambient + style.diffuse * lambert;
    if back {
        shade *= style.back_factor;
    }
    let shade = shade as f32;
    let (f0, f1, f2) = (l0 as f32, l1 as f32, l2 as f32);
    let mut rgb = [0.0f32; 3];
    for k in 0..3 {
        rgb[k] = ((f0 * c0[k] + f1 * c1[k] + f2 * c2[k]) * shade).min(1.0);
    }
    if shading.edges {
        let d = (l0 * heights[0]).min(l1 * heights[1]).min(l2 * heights[2]);
        let cover = (shading.edge_half + 0.5 - d).clamp(0.0, 1.0) as f32 * 0.85;
        if cover > 0.0 {
            for k in 0..3 {
                rgb[k] += cover * (shading.edge_colour[k] - rgb[k]);
            }
        }
    }
    rgb
}

/// Box-filters `layer` down to the size of `view`: background where nothing
/// was drawn, and the translucent `ghost` layer (with its opacity) over it
/// where the ghost is nearer.
fn resolve(layer: &Layer, ghost: Option<(&Layer, f32)>, view: &View, style: &Style) -> Image {
    let bg = style.background.map(|v| v as f32 / 255.0);
    let s = style.supersample as usize;
    let w = view.width as usize * s;
    let (ow, oh) = (view.width as usize, view.height as usize);
    let sample = |idx: usize| {
        let mut c = if layer.written[idx] {
            layer.colour[idx]
        } else {
            bg
        };
        if let Some((g, alpha)) = ghost
            && g.written[idx]
            && (!layer.written[idx] || g.depth[idx] > layer.depth[idx])
        {
            for k in 0..3 {
                c[k] += alpha * (g.colour[idx][k] - c[k]);
            }
        }
        c
    };
    let mut pixels = Vec::with_capacity(ow * oh);
    let norm = 1.0 / (s * s) as f32;
    for oy in 0..oh {
        for ox in 0..ow {
            let mut acc = [0.0f32; 3];
            for dy in 0..s {
                let row = (oy * s + dy) * w;
                for dx in 0..s {
                    let c = sample(row + ox * s + dx);
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
            }
            pixels.push(acc.map(|v| (v * norm * 255.0).round().clamp(0.0, 255.0) as u8));
        }
    }
    Image {
        width: view.width,
        height: view.height,
        pixels,
    }
}

/// Checks the numeric parameters of a style.
fn check_style(style: &Style) -> Result<(), RenderError> {
    let unit = |v: f64| (0.0..=1.0).contains(&v);
    if !(unit(style.ambient) && unit(style.diffuse) && unit(style.back_factor)) {
        return Err(RenderError::Invalid {
            what: "style",
            message: format!(
                "ambient {}, diffuse {} and back factor {} must be in [0, 1]",
                style.ambient, style.diffuse, style.back_factor
            ),
        });
    }
    if !(style.edge_width.is_finite() && style.edge_width >= 0.0 && style.edge_width <= 10.0) {
        return Err(RenderError::Invalid {
            what: "style",
            message: format!("edge width {} is not in [0, 10]", style.edge_width),
        });
    }
    if !(1..=4).contains(&style.supersample) {
        return Err(RenderError::Invalid {
            what: "style",
            message: format!("supersampling {} is not in 1..=4", style.supersample),
        });
    }
    Ok(())
}

/// Checks indices and coordinates of mesh number `index`.
pub(crate) fn check_mesh(index: usize, mesh: &RenderMesh<'_>) -> Result<(), RenderError> {
    let n = mesh.positions.len();
    if n == 0 {
        return Err(RenderError::Empty {
            mesh: index,
            what: "vertices",
        });
    }
    if mesh.faces.is_empty() {
        return Err(RenderError::Empty {
            mesh: index,
            what: "faces",
        });
    }
    if let Some(v) = mesh
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(RenderError::NonFinite {
            mesh: index,
            vertex: v,
        });
    }
    for (f, face) in mesh.faces.iter().enumerate() {
        if let Some(&v) = face.iter().find(|&&v| v >= n) {
            return Err(RenderError::FaceIndex {
                mesh: index,
                face: f,
                vertex: v,
                n,
            });
        }
    }
    Ok(())
}

/// Gives an error the index of the panel it happened in.
pub(crate) fn renumber(e: RenderError, index: usize) -> RenderError {
    match e {
        RenderError::Empty { what, .. } => RenderError::Empty { mesh: index, what },
        RenderError::FaceIndex {
            face, vertex, n, ..
        } => RenderError::FaceIndex {
            mesh: index,
            face,
            vertex,
            n,
        },
        RenderError::HighlightIndex { vertex, n, .. } => RenderError::HighlightIndex {
            mesh: index,
            vertex,
            n,
        },
        RenderError::ColourCount { got, n, .. } => RenderError::ColourCount {
            mesh: index,
            got,
            n,
        },
        RenderError::NonFinite { vertex, .. } => RenderError::NonFinite {
            mesh: index,
            vertex,
        },
        other => other,
    }
}

/// Per-vertex colours in `[0, 1]`, after checking the mesh.
fn vertex_colours(
    index: usize,
    mesh: &RenderMesh<'_>,
    style: &Style,
) -> Result<Vec<[f32; 3]>, RenderError> {
    check_mesh(index, mesh)?;
    let n = mesh.positions.len();
    let f = |c: [u8; 3]| c.map(|v| v as f32 / 255.0);
    Ok(match mesh.colouring {
        Colouring::Uniform => vec![f(style.base); n],
        Colouring::PerVertex(colours) => {
            if colours.len() != n {
                return Err(RenderError::ColourCount {
                    mesh: index,
                    got: colours.len(),
                    n,
                });
            }
            colours.iter().map(|&c| f(c)).collect()
        }
        Colouring::Highlight(vertices) => {
            let mut out = vec![f(style.base); n];
            for &v in vertices {
                if v >= n {
                    return Err(RenderError::HighlightIndex {
                        mesh: index,
                        vertex: v,
                        n,
                    });
                }
                out[v] = f(style.highlight);
            }
            out
        }
    })
}

/// Area-weighted vertex normals (unit length, or zero for a vertex whose
/// faces cancel out).
fn vertex_normals(positions: &[[f64; 3]], faces: &[[usize; 3]]) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; positions.len()];
    for &[a, b, c] in faces {
        let n = cross(
            sub3(positions[b], positions[a]),
            sub3(positions[c], positions[a]),
        );
        for v in [a, b, c] {
            normals[v] = add3(normals[v], n);
        }
    }
    for n in &mut normals {
        let len = dot(*n, *n).sqrt();
        *n = if len > 0.0 {
            scale3(*n, 1.0 / len)
        } else {
            [0.0; 3]
        };
    }
    normals
}

/// Mean projected edge length, pixels (each face's three edges).
fn mean_edge_pixels(projected: &[[f64; 3]], faces: &[[usize; 3]]) -> f64 {
    if faces.is_empty() {
        return 0.0;
    }
    let len = |p: [f64; 3], q: [f64; 3]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
    let total: f64 = faces
        .iter()
        .map(|&[a, b, c]| {
            let (pa, pb, pc) = (projected[a], projected[b], projected[c]);
            len(pa, pb) + len(pb, pc) + len(pc, pa)
        })
        .sum();
    total / (3 * faces.len()) as f64
}

/// Twice the signed area of `(a, b, p)` in screen coordinates.
#[inline]
fn edge_fn(a: [f64; 3], b: [f64; 3], px: f64, py: f64) -> f64 {
    (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
}

/// Dot product.
#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product.
#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a − b`.
#[inline]
fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a + b`.
#[inline]
fn add3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `s · a`.
#[inline]
fn scale3(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `a / |a|` (zero stays zero).
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let len = dot(a, a).sqrt();
    if len > 0.0 { scale3(a, 1.0 / len) } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn screen_triangle_bounds_and_refusals() {
        let tri = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        assert_eq!(screen_triangle(tri, 10, 10), Some((16.0, [0, 0, 4, 4])));
        assert_eq!(screen_triangle(tri, 3, 2), Some((16.0, [0, 0, 3, 2])));
        let edge_on = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(screen_triangle(edge_on, 10, 10), None);
        let left = [[-5.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [-5.0, 4.0, 0.0]];
        assert_eq!(screen_triangle(left, 10, 10), None);
        let huge = [[0.0, 0.0, 0.0], [f64::MAX, 0.0, 0.0], [0.0, f64::MAX, 0.0]];
        assert_eq!(screen_triangle(huge, 10, 10), None);
    }

    #[test]
    fn edge_heights_of_a_3_4_5_triangle() {
        let tri = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        assert_eq!(edge_heights(tri, 12.0), [2.4, 3.0, 4.0]);
    }

    fn flat_triangle(colour: f32) -> Triangle {
        Triangle {
            corners: [[0.0, 0.0, 1.0], [4.0, 0.0, 1.0], [0.0, 4.0, 1.0]],
            area: 16.0,
            normals: [[0.0, 0.0, 1.0]; 3],
            face_normal: [0.0, 0.0, 1.0],
            colours: [[colour; 3]; 3],
        }
    }

    fn shading(edges: bool) -> Shading {
        Shading {
            key: [0.0, 0.0, 1.0],
            toward: [0.0, 0.0, 1.0],
            edges,
            edge_half: 0.5,
            edge_colour: [1.0; 3],
        }
    }

    #[test]
    fn draw_triangle_covers_the_samples_inside_once() {
        let mut layer = Layer {
            colour: vec![[0.0; 3]; 16],
            depth: vec![f32::NEG_INFINITY; 16],
            written: vec![false; 16],
        };
        let t = flat_triangle(0.5);
        let style = Style::default();
        // Sample centres (x + ½, y + ½) inside x + y ≤ 3: 4 + 3 + 2 + 1.
        let n = draw_triangle(&mut layer, 4, [0, 0, 4, 4], &t, &shading(false), &style);
        assert_eq!(n, 10);
        let inside: Vec<bool> = (0..16).map(|i| i % 4 + i / 4 <= 3).collect();
        assert_eq!(layer.written, inside);
        // The same triangle again is not nearer: nothing written.
        assert_eq!(
            draw_triangle(&mut layer, 4, [0, 0, 4, 4], &t, &shading(false), &style),
            0
        );
    }

    #[test]
    fn shade_sample_ambient_back_factor_and_edge_blend() {
        let style = Style {
            ambient: 0.2,
            diffuse: 0.0,
            back_factor: 0.5,
            ..Style::default()
        };
        let l = [0.5, 0.5, 0.0];
        let t = flat_triangle(0.5);
        assert_eq!(
            shade_sample(l, false, [0.0; 3], &t, &shading(false), &style),
            [0.1; 3]
        );
        assert_eq!(
            shade_sample(l, true, [0.0; 3], &t, &shading(false), &style),
            [0.05; 3]
        );
        // On an edge (l2 = 0): 85 % of the edge colour over black.
        let black = flat_triangle(0.0);
        assert_eq!(
            shade_sample(l, false, [1.0; 3], &black, &shading(true), &style),
            [0.85; 3]
        );
    }
    use crate::mesh::generate;

    /// A style without shading subtleties: no supersampling, no edges.
    fn plain() -> Style {
        Style {
            supersample: 1,
            edges: Edges::Off,
            ..Style::default()
        }
    }

    /// Front view (looking down −z, x right, y up).
    fn front() -> Camera {
        Camera::new(0.0, 0.0)
    }

    #[test]
    fn one_triangle_facing_the_camera_covers_its_half_of_the_image() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let faces = [[0, 1, 2]];
        let view = View::fit(&front(), &[&positions], 100, 100, 0.0).unwrap();
        let (image, stats) =
            render_with_stats(&RenderMesh::new(&positions, &faces), &view, &plain()).unwrap();
        // The triangle maps to the lower-left half: pixel (x, y) is covered
        // iff x ≤ y (pixel centres on the diagonal lie on the edge).
        let bg = plain().background;
        let mut covered = 0;
        for y in 0..100 {
            for x in 0..100 {
                let p = image.get(x, y).unwrap();
                if x < y {
                    assert_ne!(p, bg, "({x}, {y}) should be covered");
                } else if x > y {
                    assert_eq!(p, bg, "({x}, {y}) should be background");
                }
                if p != bg {
                    covered += 1;
                }
            }
        }
        assert!((4950..=5050).contains(&covered), "{covered}");
        assert_eq!(stats.triangles_drawn, 1);
        assert!(!stats.edges);
        // Front facing and lit: grey, brighter than the ambient term alone.
        let p = image.get(10, 80).unwrap();
        assert!(
            p[0] == p[1] && p[0] > (200.0 * plain().ambient) as u8 + 20,
            "{p:?}"
        );
    }

    #[test]
    fn the_nearer_of_two_overlapping_triangles_wins_in_either_order() {
        // Two triangles over the same square, z = 0 (red) and z = 1 (blue,
        // nearer to a camera on +z).
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        let colours = [
            [255, 0, 0],
            [255, 0, 0],
            [255, 0, 0],
            [0, 0, 255],
            [0, 0, 255],
            [0, 0, 255],
        ];
        for faces in [[[0, 1, 2], [3, 4, 5]], [[3, 4, 5], [0, 1, 2]]] {
            let mesh = RenderMesh::new(&positions, &faces).colours(&colours);
            let view = View::fit(&front(), &[&positions], 60, 60, 0.0).unwrap();
            let image = render(&mesh, &view, &plain()).unwrap();
            let p = image.get(10, 50).unwrap();
            assert!(
                p[2] > 100 && p[0] == 0,
                "blue should win, got {p:?} for {faces:?}"
            );
        }
        // Seen from behind (azimuth 180°), the red one is nearer.
        let faces = [[0, 1, 2], [3, 4, 5]];
        let mesh = RenderMesh::new(&positions, &faces).colours(&colours);
        let view = View::fit(&Camera::new(180.0, 0.0), &[&positions], 60, 60, 0.0).unwrap();
        let image = render(&mesh, &view, &plain()).unwrap();
        // x is mirrored from behind: the triangle is in the lower right.
        let p = image.get(50, 50).unwrap();
        assert!(
            p[0] > 100 && p[2] == 0,
            "red should win from behind, got {p:?}"
        );
    }

    #[test]
    fn a_highlighted_vertex_colours_its_neighbourhood_red() {
        let grid = generate::grid(10, 10).unwrap();
        let centre = 5 * 11 + 5; // vertex (5, 5) at (0.5, 0.5, 0)
        let highlighted = [centre];
        let mesh = RenderMesh::from_mesh(&grid).highlight(&highlighted);
        let view = View::fit(&front(), &[grid.positions()], 110, 110, 0.0).unwrap();
        let image = render(&mesh, &view, &plain()).unwrap();
        let [x, y, _] = view.project(grid.positions()[centre]);
        let near = image.get(x as u32, y as u32).unwrap();
        assert!(
            near[0] > 2 * near[1] && near[0] > 2 * near[2],
            "red near the vertex: {near:?}"
        );
        // A vertex's neighbourhood ends one cell (11 pixels) away.
        let far = image.get(x as u32 + 30, y as u32).unwrap();
        assert!(far[0] == far[1], "grey away from it: {far:?}");
    }

    #[test]
    fn open_meshes_are_shaded_from_behind_too() {
        let grid = generate::grid(4, 4).unwrap();
        let mesh = RenderMesh::from_mesh(&grid);
        let front_view = View::fit(&front(), &[grid.positions()], 40, 40, 0.1).unwrap();
        let back_view =
            View::fit(&Camera::new(180.0, 0.0), &[grid.positions()], 40, 40, 0.1).unwrap();
        let a = render(&mesh, &front_view, &plain())
            .unwrap()
            .get(20, 20)
            .unwrap();
        let b = render(&mesh, &back_view, &plain())
            .unwrap()
            .get(20, 20)
            .unwrap();
        let ambient_only = (200.0 * plain().ambient) as u8;
        assert!(a[0] > ambient_only + 20, "{a:?}");
        // The back side is lit like the front, times the back factor.
        assert!(b[0] > ambient_only + 20 && b[0] < a[0], "{b:?} vs {a:?}");
    }

    #[test]
    fn edges_are_drawn_on_large_triangles_only_with_auto() {
        let grid = generate::grid(2, 2).unwrap();
        let mesh = RenderMesh::from_mesh(&grid);
        let view = View::fit(&front(), &[grid.positions()], 100, 100, 0.0).unwrap();
        let style = Style {
            edges: Edges::Auto,
            ..plain()
        };
        let (image, stats) = render_with_stats(&mesh, &view, &style).unwrap();
        assert!(stats.edges);
        // The vertical grid line x = 0.5 runs through pixel column 50.
        let on_edge = image.get(50, 25).unwrap();
        let off_edge = image.get(30, 25).unwrap();
        assert!(on_edge[0] + 30 < off_edge[0], "{on_edge:?} vs {off_edge:?}");
        let big = generate::grid(100, 100).unwrap();
        let (_, stats) = render_with_stats(&RenderMesh::from_mesh(&big), &view, &style).unwrap();
        assert!(!stats.edges);
    }

    #[test]
    fn camera_from_direction_inverts_azimuth_and_elevation() {
        let c = Camera::from_direction([0.0, 0.0, 2.0], 1).unwrap();
        assert!(c.azimuth_deg.abs() < 1e-12 && c.elevation_deg.abs() < 1e-12);
        let c = Camera::from_direction([1.0, 1.0, 0.0], 2).unwrap();
        assert!((c.azimuth_deg - 45.0).abs() < 1e-12 && c.elevation_deg.abs() < 1e-12);
        let original = Camera::new(-70.0, 15.0).with_up_axis(0);
        let toward = original.basis().unwrap()[2];
        let back = Camera::from_direction(toward, 0).unwrap();
        assert!((back.azimuth_deg + 70.0).abs() < 1e-9 && (back.elevation_deg - 15.0).abs() < 1e-9);
        assert!(Camera::from_direction([0.0, 1.0, 0.0], 1).is_err());
        assert!(Camera::from_direction([0.0; 3], 1).is_err());
    }

    #[test]
    fn shared_framing_keeps_the_original_in_place() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let moved: Vec<[f64; 3]> = positions.iter().map(|p| [p[0] + 2.0, p[1], p[2]]).collect();
        let alone = View::fit(&front(), &[&positions], 100, 100, 0.0).unwrap();
        let shared = View::fit(&front(), &[&positions, &moved], 100, 100, 0.0).unwrap();
        // Alone, the triangle fills the image; shared, it is a third as wide.
        assert!((alone.project([1.0, 0.0, 0.0])[0] - 100.0).abs() < 1e-9);
        let [x0, ..] = shared.project([0.0, 0.0, 0.0]);
        let [x1, ..] = shared.project([1.0, 0.0, 0.0]);
        assert!(((x1 - x0) - 100.0 / 3.0).abs() < 1e-9, "{x0} {x1}");
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let view = View::fit(&front(), &[&positions], 10, 10, 0.0).unwrap();
        let bad_face = [[0, 1, 3]];
        assert!(matches!(
            render(&RenderMesh::new(&positions, &bad_face), &view, &plain()),
            Err(RenderError::FaceIndex { vertex: 3, .. })
        ));
        let faces = [[0, 1, 2]];
        let nan = [[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(matches!(
            render(&RenderMesh::new(&nan, &faces), &view, &plain()),
            Err(RenderError::NonFinite { vertex: 1, .. })
        ));
        let hl = [7];
        assert!(matches!(
            render(
                &RenderMesh::new(&positions, &faces).highlight(&hl),
                &view,
                &plain()
            ),
            Err(RenderError::HighlightIndex { vertex: 7, .. })
        ));
        let few = [[1u8, 2, 3]];
        assert!(matches!(
            render(
                &RenderMesh::new(&positions, &faces).colours(&few),
                &view,
                &plain()
            ),
            Err(RenderError::ColourCount { got: 1, n: 3, .. })
        ));
        assert!(matches!(
            View::fit(&Camera::new(0.0, 90.0), &[&positions], 10, 10, 0.0),
            Err(RenderError::Invalid { what: "camera", .. })
        ));
        assert!(matches!(
            View::fit(&front(), &[&positions], 0, 10, 0.0),
            Err(RenderError::BadSize { .. })
        ));
        // Coordinates near f64::MAX: no panic, nothing drawn over the image.
        let huge = [
            [0.0, 0.0, 0.0],
            [1e308, 0.0, 0.0],
            [0.0, 1e308, 0.0],
            [-1e308, -1e308, 0.0],
        ];
        let huge_faces = [[0, 1, 2], [0, 3, 1]];
        let huge_view = View::fit(&front(), &[&positions], 10, 10, 0.0).unwrap();
        let image = render(&RenderMesh::new(&huge, &huge_faces), &huge_view, &plain()).unwrap();
        assert_eq!(image.pixels.len(), 100);
        let empty: [[usize; 3]; 0] = [];
        assert!(matches!(
            render(&RenderMesh::new(&positions, &empty), &view, &plain()),
            Err(RenderError::Empty { what: "faces", .. })
        ));
    }
}
