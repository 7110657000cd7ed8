//! `editor`: the interactive editor's drag in headless Chromium, the
//! client path (the response basis evaluated in the vertex shader, one
//! transform uploaded per frame) against the server path (one POST and one
//! positions download per frame), on the Bunny and the 537k-vertex Igea
//! (else the first mesh given, else a generated bumpy sphere).
//!
//! `experiments/editor_frames.mjs` drives the page through playwright-core
//! with Chromium's software renderer (SwiftShader): per mesh and path a
//! drag of [`FRAMES`] frames without drawing and a shorter one with
//! drawing (software drawing of 1 M triangles takes about two seconds a
//! frame), the page's screenshots and `lse-deform render`'s image of the
//! same view. Node, playwright-core and Chromium are found or installed as
//! [`environment::browser`] says; without them the section says what was
//! not measured and why.

use std::fmt::Write as _;
use std::path::PathBuf;

use lse_deform::mesh::write_mesh;
use serde::{Deserialize, Serialize};

use crate::harness::context::AnyError;
use crate::harness::context::Context;
use crate::harness::environment;
use crate::harness::registry::{Experiment, Input, Summary};
use crate::harness::rows::markdown_table;

pub const NAME: &str = "editor";

/// This study's entry in the list of experiments.
pub const EXPERIMENT: Experiment = Experiment {
    name: NAME,
    title: "The interactive editor in a browser — client path against server path",
    inputs: &[Input::Meshes, Input::Browser],
    run,
};

/// Frames of the drags without drawing.
const FRAMES: usize = 300;
/// Frames of the drags with drawing: fewer on large meshes, whose software
/// drawing takes seconds a frame.
fn drawn_frames(vertices: usize, quick: bool) -> usize {
    match (quick, vertices) {
        (true, _) => 5,
        (false, v) if v > 200_000 => 10,
        (false, _) => 30,
    }
}

/// One drag as the page reports it (`window.editor.scriptedDrag`).
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "camelCase")]
struct Drag {
    frames: usize,
    fps: f64,
    bytes_per_frame: f64,
    js_median_ms: f64,
    js_mean_ms: f64,
    upload_median_ms: f64,
    render_median_ms: f64,
    server_frame_median_ms: Option<f64>,
    download_median_ms: Option<f64>,
}

/// One path's drags and its read-back agreement.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "camelCase")]
struct PathResult {
    without: Drag,
    with: Drag,
    readback_error: f64,
}

/// The ARAP drag (server path) and the report's median time per
/// iteration.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "camelCase")]
struct ArapResult {
    without: Drag,
    iterations_per_frame: usize,
    time_per_iteration_s: f64,
}

#[derive(Debug, Clone, Deserialize)]
struct Paths {
    client: PathResult,
    server: PathResult,
    arap: Option<ArapResult>,
}

/// One row of `editor/arap_frames.csv`: a mesh's ARAP drag.
#[derive(Debug, Clone, Serialize)]
struct ArapRow {
    mesh: String,
    vertices: usize,
    frames: usize,
    iterations_per_frame: usize,
    fps_undrawn: f64,
    server_frame_median_ms: Option<f64>,
    iterations_per_s: f64,
}

impl ArapRow {
    fn new(m: &MeshResult, r: &ArapResult) -> ArapRow {
        ArapRow {
            mesh: m.name.clone(),
            vertices: m.vertices,
            frames: r.without.frames,
            iterations_per_frame: r.iterations_per_frame,
            fps_undrawn: r.without.fps,
            server_frame_median_ms: r.without.server_frame_median_ms,
            iterations_per_s: 1.0 / r.time_per_iteration_s,
        }
    }
}

/// ARAP frames per drag: fewer on large meshes (each frame runs the
/// iterations of a global solve).
fn arap_frames(vertices: usize, quick: bool) -> usize {
    match (quick, vertices) {
        (true, _) => 5,
        (false, v) if v > 200_000 => 20,
        (false, _) => 60,
    }
}

/// One mesh of `frames.json`.
#[derive(Debug, Clone, Deserialize)]
struct MeshResult {
    name: String,
    vertices: usize,
    rows: Paths,
}

/// Which way a frame's positions reach the page.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum FramePath {
    Client,
    Server,
}

/// One row of `editor/frames.csv`: a mesh and a path.
#[derive(Debug, Clone, Serialize)]
struct Row {
    mesh: String,
    vertices: usize,
    path: FramePath,
    frames_undrawn: usize,
    frames_drawn: usize,
    bytes_per_frame: f64,
    fps_undrawn: f64,
    fps_drawn: f64,
    js_median_ms: f64,
    js_mean_ms: f64,
    upload_median_ms: f64,
    drawn_median_ms: f64,
    server_frame_median_ms: Option<f64>,
    download_median_ms: Option<f64>,
    displayed_vs_f64_over_diagonal: f64,
}

impl Row {
    fn new(m: &MeshResult, path: FramePath, r: &PathResult) -> Row {
        Row {
            mesh: m.name.clone(),
            vertices: m.vertices,
            path,
            frames_undrawn: r.without.frames,
            frames_drawn: r.with.frames,
            bytes_per_frame: r.without.bytes_per_frame,
            fps_undrawn: r.without.fps,
            fps_drawn: r.with.fps,
            js_median_ms: r.with.js_median_ms,
            js_mean_ms: r.with.js_mean_ms,
            upload_median_ms: r.with.upload_median_ms,
            drawn_median_ms: r.with.render_median_ms,
            server_frame_median_ms: r.without.server_frame_median_ms,
            download_median_ms: r.without.download_median_ms,
            displayed_vs_f64_over_diagonal: r.readback_error,
        }
    }
}

/// The mesh files to drag: the Bunny and Igea if given, else the first
/// user mesh, else a generated bumpy sphere written to `work`.
fn mesh_files(ctx: &Context, work: &std::path::Path) -> Result<Vec<PathBuf>, AnyError> {
    let named: Vec<PathBuf> = ["bunny-35k-stanford.obj", "igea-537k-subdiv.obj"]
        .iter()
        .filter_map(|f| ctx.mesh_file(f).map(PathBuf::from))
        .collect();
    if !named.is_empty() {
        return Ok(named);
    }
    if let Some(first) = ctx.mesh_files.first() {
        return Ok(vec![first.clone()]);
    }
    let case = ctx.fallback_mesh("", 35_000, 3_000)?;
    let path = work.join(format!("{}.obj", case.name));
    write_mesh(&case.mesh, &path)?;
    Ok(vec![path])
}

/// The browser's end-to-end test (`tests/browser/editor.test.mjs`, as
/// `.ci/run` runs it) with its screenshot as `dir/e2e.png`; `Err` with the
/// test's last line if it fails.
fn end_to_end(
    dir: &std::path::Path,
    bin: &std::path::Path,
    chromium: &std::path::Path,
) -> Result<(), AnyError> {
    let tests = environment::workspace_root().join("tests").join("browser");
    let out = environment::child("node")
        .arg("editor.test.mjs")
        .current_dir(&tests)
        .env("LSE_DEFORM_BIN", bin)
        .env("CHROMIUM", chromium)
        .env("SCREENSHOT", std::path::absolute(dir.join("e2e.png"))?)
        .output()?;
    if out.status.success() {
        Ok(())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        Err(format!(
            "the end-to-end test failed: {}",
            err.lines().last().unwrap_or("")
        )
        .into())
    }
}

/// Runs `editor_frames.mjs` on every mesh, the screenshots into `dir`,
/// then the end-to-end test.
fn measure(ctx: &Context, dir: &std::path::Path) -> Result<(Vec<Row>, Vec<ArapRow>), AnyError> {
    let browser = environment::browser()?;
    let bin = environment::cli_binary()?;
    end_to_end(dir, &bin, &browser.chromium)?;
    let work = std::env::temp_dir().join(format!("lse-editor-{}", std::process::id()));
    std::fs::create_dir_all(&work)?;
    let (mut rows, mut arap) = (Vec::new(), Vec::new());
    for mesh in mesh_files(ctx, &work)? {
        let vertices =
            lse_deform::mesh::read_mesh(&mesh, lse_deform::limits::MemoryBudget::default())?
                .mesh
                .n_vertices();
        let frames = if ctx.quick { 30 } else { FRAMES };
        let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("editor_frames.mjs");
        let status = environment::child("node")
            .arg(script)
            .args(["--frames", &frames.to_string()])
            .args([
                "--drawn-frames",
                &drawn_frames(vertices, ctx.quick).to_string(),
            ])
            .args([
                "--arap-frames",
                &arap_frames(vertices, ctx.quick).to_string(),
            ])
            .arg("--out")
            .arg(dir)
            .arg(&mesh)
            .env("LSE_DEFORM_BIN", &bin)
            .env("CHROMIUM", &browser.chromium)
            .stdout(std::process::Stdio::null())
            .status()?;
        if !status.success() {
            return Err(format!("editor_frames.mjs failed on {}", mesh.display()).into());
        }
        let measured: Vec<MeshResult> =
            serde_json::from_slice(&std::fs::read(dir.join("frames.json"))?)?;
        for m in &measured {
            rows.push(Row::new(m, FramePath::Client, &m.rows.client));
            rows.push(Row::new(m, FramePath::Server, &m.rows.server));
            arap.extend(m.rows.arap.as_ref().map(|r| ArapRow::new(m, r)));
        }
    }
    std::fs::remove_file(dir.join("frames.json"))?;
    let _ = std::fs::remove_dir_all(&work);
    Ok((rows, arap))
}

/// Runs the experiment.
pub fn run(ctx: &Context) -> Result<Summary, AnyError> {
    let dir = ctx.dir(NAME)?;
    let (md, summary) = match measure(ctx, &dir) {
        Ok((rows, arap)) => {
            ctx.write_rows(&dir.join("frames"), &rows)?;
            ctx.write_rows(&dir.join("arap_frames"), &arap)?;
            (
                section(ctx, &rows, &arap),
                Summary::measured(headline(&rows)),
            )
        }
        Err(why) => {
            let (md, why) = not_measured(ctx, &why.to_string());
            (md, Summary::skipped(why))
        }
    };
    ctx.write_section(NAME, &md)?;
    ctx.write_page(NAME, EXPERIMENT.title, &md)?;
    Ok(summary)
}

fn num(x: f64) -> String {
    if x >= 100.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.3}")
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or_else(|| "–".into(), num)
}

fn headline(rows: &[Row]) -> String {
    let parts: Vec<String> = rows
        .iter()
        .filter(|r| r.path == FramePath::Server)
        .filter_map(|s| {
            let c = rows
                .iter()
                .find(|c| c.mesh == s.mesh && c.path == FramePath::Client)?;
            Some(format!(
                "{}: {} vs {} bytes/frame, {} vs {} frames/s undrawn (client vs server path)",
                s.mesh,
                num(c.bytes_per_frame),
                num(s.bytes_per_frame),
                num(c.fps_undrawn),
                num(s.fps_undrawn)
            ))
        })
        .collect();
    parts.join("; ")
}

/// The ARAP frames table and its finding.
fn arap_section(arap: &[ArapRow]) -> String {
    let mut s = String::from(
        "\n**ARAP frames.** After `PUT /api/settings {\"energy\": \"arap\"}` the same handle is dragged on the server path (ARAP has no response basis): \
         each frame runs the session's ARAP iterations per frame (`arap_iterations_per_frame`), warm-started from the last frame's positions, and downloads the positions. \
         Iterations/s is 1 / the report's median time per iteration (`arap.time_per_iteration_s`), the figure the page's HUD shows.\n\n",
    );
    let table: Vec<Vec<String>> = arap
        .iter()
        .map(|r| {
            vec![
                format!("{} ({} vertices)", r.mesh, r.vertices),
                r.frames.to_string(),
                r.iterations_per_frame.to_string(),
                num(r.fps_undrawn),
                opt(r.server_frame_median_ms),
                num(r.iterations_per_s),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "mesh",
            "frames",
            "iterations/frame",
            "frames/s undrawn",
            "server compute ms/frame",
            "ARAP iterations/s",
        ],
        &table,
    ));
    s
}

fn section(ctx: &Context, rows: &[Row], arap: &[ArapRow]) -> String {
    let mut s = ctx.regenerate(NAME);
    let _ = writeln!(
        s,
        "A scripted drag of the `lse-deform scene` handle (20 % `fixed`, a 2 % `handle`, null-space QR, cotangent, refinement auto) along a circle of a quarter of the bounding radius, \
         in headless Chromium with SwiftShader (software rendering: no GPU), the page with `?mode=client` and then `?mode=server` on the same server. \
         Each row is {FRAMES} frames without drawing, then fewer with drawing (the \"drawn\" column gives how many: software drawing takes seconds a frame on large meshes, so the drawn pass is capped). \
         Bytes per frame are HTTP body bytes in both directions over the drag, final POST included. \"Displayed vs f64\" is the shader's read-back positions (client) or the f32 download (server) against the server's f64 positions.\n"
    );
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                format!("{} ({} vertices)", r.mesh, r.vertices),
                format!("{:?}", r.path).to_lowercase(),
                num(r.bytes_per_frame),
                format!("{} / {}", r.frames_undrawn, r.frames_drawn),
                num(r.fps_undrawn),
                num(r.fps_drawn),
                format!("{} ({})", num(r.js_median_ms), num(r.js_mean_ms)),
                num(r.upload_median_ms),
                num(r.drawn_median_ms),
                opt(r.server_frame_median_ms),
                opt(r.download_median_ms),
                format!("{:.2e}", r.displayed_vs_f64_over_diagonal),
            ]
        })
        .collect();
    s.push_str(&markdown_table(
        &[
            "mesh",
            "path",
            "bytes/frame",
            "frames undrawn / drawn",
            "frames/s undrawn",
            "frames/s drawn",
            "JS ms/frame drawn, median (mean)",
            "upload ms/frame",
            "until drawn ms/frame",
            "server compute ms/frame",
            "download ms/frame",
            "displayed vs f64, max / diagonal",
        ],
        &table,
    ));
    let _ = writeln!(s, "\nIn short: {}.\n", headline(rows));
    if !arap.is_empty() {
        s.push_str(&arap_section(arap));
        s.push('\n');
    }
    let mut meshes: Vec<&str> = rows.iter().map(|r| r.mesh.as_str()).collect();
    meshes.dedup();
    for m in meshes {
        let _ = writeln!(
            s,
            "{m}: the page ![page]({NAME}/{m}-page.png), with the page's former near plane (1e-6 of the bounding radius: back faces win the depth test) ![former near plane]({NAME}/{m}-page-former-near-plane.png), and `lse-deform render` from the same direction (orthographic) ![render]({NAME}/{m}-render.png)\n"
        );
    }
    let _ = writeln!(
        s,
        "The end-to-end test (`tests/browser/editor.test.mjs`, passed in this run) on a generated 4k-vertex grid after the mouse brushed a fixed corner and a handle and dragged the handle with the move tool: ![end-to-end test]({NAME}/e2e.png)\n"
    );
    s.push_str(&ctx.closing(
        &["This machine has no GPU: the drawn frame rates are SwiftShader's, on the same cores as the server.".into()],
        "Data: `editor/frames.csv` and `editor/arap_frames.csv` (and `.json`).",
    ));
    s
}

fn not_measured(ctx: &Context, why: &str) -> (String, String) {
    let mut s = ctx.regenerate(NAME);
    let _ = writeln!(
        s,
        "**Not measured:** the editor's drag in a browser (client against server path, frame rates, bytes per frame, read-back agreement) and its screenshots, because {why}. \
         The experiment needs `node` and `npm`, Chromium (`chromium` on PATH or `$CHROMIUM`) and playwright-core (`npm ci` in `tests/browser`, run if missing), as `.ci/run`'s browser test."
    );
    s.push_str(&ctx.closing(&[], "No data files."));
    (s, format!("not measured: {why}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One path's drags as `editor_frames.mjs` writes them (the page's
    /// `scriptedDrag` fields, camelCase).
    fn path_json(fps: f64, server: Option<f64>) -> serde_json::Value {
        let drag = |frames: usize, fps: f64| {
            serde_json::json!({
                "frames": frames, "path": "x", "seconds": 1.0, "fps": fps, "rendered": false,
                "bytesPerFrame": 0.5, "bytes": {"sent": 82, "received": 79},
                "jsMedianMs": 0.2, "jsMeanMs": 0.4, "uploadMeanMs": 0.1, "renderMeanMs": 2.0,
                "uploadMedianMs": 0.1, "renderMedianMs": 1.5,
                "serverFrameMedianMs": server, "serverRequestMedianMs": server,
                "postMedianMs": server, "downloadMedianMs": server,
            })
        };
        serde_json::json!({"without": drag(300, fps), "with": drag(30, 4.0), "readbackError": 5e-8})
    }

    #[test]
    fn rows_take_undrawn_rates_and_drawn_times_from_the_scripts_json() {
        let doc = serde_json::json!([{
            "name": "bunny", "vertices": 34834, "frames": 300, "drawnFrames": 30,
            "rows": {"client": path_json(12000.0, None), "server": path_json(65.0, Some(0.2))},
        }]);
        let parsed: Vec<MeshResult> = serde_json::from_value(doc).expect("the script's format");
        let m = &parsed[0];
        let client = Row::new(m, FramePath::Client, &m.rows.client);
        let server = Row::new(m, FramePath::Server, &m.rows.server);
        assert_eq!((client.frames_undrawn, client.frames_drawn), (300, 30));
        assert_eq!((client.fps_undrawn, client.fps_drawn), (12000.0, 4.0));
        assert_eq!(client.server_frame_median_ms, None);
        assert_eq!(server.server_frame_median_ms, Some(0.2));
        assert_eq!(server.fps_undrawn, 65.0);
        assert_eq!(server.drawn_median_ms, 1.5);
        assert_eq!(server.displayed_vs_f64_over_diagonal, 5e-8);
    }
}
