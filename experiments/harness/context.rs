//! What every experiment shares: where results go, which meshes to use, the
//! seed, the machine description recorded in every output, progress bars,
//! and the writers for CSV, JSON and README sections.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use lse_deform::mesh::{Mesh, generate, read_mesh};
use serde::Serialize;

/// Any failure of an experiment, as one line.
pub type AnyError = Box<dyn std::error::Error>;

/// The machine, build and inputs an output was produced with.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// CPU model (from `/proc/cpuinfo`).
    pub cpu: String,
    /// Logical cores available to this process.
    pub cores: usize,
    /// Total memory in GiB (from `/proc/meminfo`).
    pub memory_gib: f64,
    /// Operating system and architecture.
    pub os: String,
    /// `lse-deform` version.
    pub crate_version: String,
    /// `git rev-parse --short HEAD` (with `-dirty` if the tree has
    /// uncommitted changes), or "unknown".
    pub git_revision: String,
    /// Cargo features compiled in.
    pub features: Vec<String>,
    /// Build profile ("release" or "debug").
    pub profile: String,
    /// The command line.
    pub command: String,
    /// Seed of every random choice.
    pub seed: u64,
    /// Mesh directory, or "generated meshes".
    pub meshes: String,
}

impl Machine {
    fn detect(seed: u64, meshes: Option<&str>) -> Machine {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let cpu = cpuinfo
            .lines()
            .find_map(|l| {
                l.strip_prefix("model name")
                    .map(|r| r.trim_start_matches([' ', '\t', ':']).to_string())
            })
            .unwrap_or_else(|| "unknown".into());
        let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
        let memory_gib = meminfo
            .lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|r| r.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
            .map(|kb| kb / 1024.0 / 1024.0)
            .unwrap_or(0.0);
        let git = |args: &[&str]| {
            std::process::Command::new("git")
                .args(args)
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .output()
                .ok()
                .filter(|o| o.status.success())
                .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        };
        let git_revision = match git(&["rev-parse", "--short", "HEAD"]) {
            Some(rev) => {
                let dirty = git(&["status", "--porcelain", "--untracked-files=no"])
                    .is_some_and(|s| !s.is_empty());
                if dirty { format!("{rev}-dirty") } else { rev }
            }
            None => "unknown".into(),
        };
        let mut features = Vec::new();
        if cfg!(feature = "suitesparse") {
            features.push("suitesparse".to_string());
        }
        if cfg!(feature = "mumps") {
            features.push("mumps".to_string());
        }
        Machine {
            cpu,
            cores: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1),
            memory_gib,
            os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
            crate_version: env!("CARGO_PKG_VERSION").into(),
            git_revision,
            features,
            profile: if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            }
            .into(),
            // The program as `experiments`, not the path it was started
            // from (which names a machine's directories).
            command: std::iter::once("experiments".to_string())
                .chain(std::env::args().skip(1))
                .collect::<Vec<_>>()
                .join(" "),
            seed,
            meshes: meshes
                .map(str::to_string)
                .unwrap_or_else(|| "generated meshes".into()),
        }
    }

    /// One line for the head of a CSV file or a section.
    pub fn one_line(&self) -> String {
        format!(
            "lse-deform {} (git {}, {}{}), {} x {}, {:.0} GiB, {}; seed {}; {}",
            self.crate_version,
            self.git_revision,
            self.profile,
            if self.features.is_empty() {
                String::new()
            } else {
                format!(", features: {}", self.features.join(","))
            },
            self.cores,
            self.cpu,
            self.memory_gib,
            self.os,
            self.seed,
            self.meshes
        )
    }
}

/// A mesh an experiment runs on.
#[derive(Debug, Clone)]
pub struct MeshCase {
    /// Short name used in tables and file names ("bunny-35k", "sliver").
    pub name: String,
    /// The mesh.
    pub mesh: Mesh,
    /// Where it came from (a file path or the generator and its size).
    pub source: String,
}

/// The shared state of a run.
pub struct Context {
    /// The results directory (`results/` by default).
    pub out: PathBuf,
    /// The real meshes' directory, if given.
    pub mesh_dir: Option<PathBuf>,
    /// The meshes named one by one (`--mesh`).
    pub mesh_paths: Vec<PathBuf>,
    /// The user's constraint file for the `--mesh` files (`-c`).
    pub constraints: Option<PathBuf>,
    /// Every user mesh file: the `--mesh` paths, then the mesh files of
    /// `--mesh-dir` sorted by name (see [`mesh_files_in`]).
    pub mesh_files: Vec<PathBuf>,
    /// Smaller sizes and fewer repetitions (for smoke tests).
    pub quick: bool,
    /// Seed of every random choice.
    pub seed: u64,
    /// The machine description.
    pub machine: Machine,
    /// Progress bars (drawn on stderr when it is a terminal).
    pub progress: MultiProgress,
}

impl Context {
    /// A context writing to `out`, on the meshes `mesh_paths` and every
    /// mesh file of `mesh_dir`. An error when a path is not a mesh file or
    /// the directory holds none.
    pub fn new(
        out: PathBuf,
        mesh_paths: Vec<PathBuf>,
        mesh_dir: Option<PathBuf>,
        constraints: Option<PathBuf>,
        quick: bool,
        seed: u64,
    ) -> Result<Context, AnyError> {
        if let Some(c) = &constraints
            && (mesh_paths.is_empty() || !c.is_file())
        {
            return Err(format!(
                "-c {}: needs an existing file and the --mesh it belongs to",
                c.display()
            )
            .into());
        }
        let mut mesh_files = Vec::new();
        for p in &mesh_paths {
            if !p.is_file() {
                return Err(format!("--mesh {}: no such file", p.display()).into());
            }
            if !is_mesh_file(p) {
                return Err(format!(
                    "--mesh {}: not a mesh file (.obj, .ply or .off, optionally .gz)",
                    p.display()
                )
                .into());
            }
            mesh_files.push(p.clone());
        }
        if let Some(dir) = &mesh_dir {
            let found = mesh_files_in(dir)?;
            if found.is_empty() {
                return Err(format!(
                    "--mesh-dir {}: no mesh files in it (.obj, .ply or .off, optionally .gz)",
                    dir.display()
                )
                .into());
            }
            for f in found {
                if !mesh_files.contains(&f) {
                    mesh_files.push(f);
                }
            }
        }
        let description = mesh_description(&mesh_paths, mesh_dir.as_deref());
        let machine = Machine::detect(seed, description.as_deref());
        Ok(Context {
            out,
            mesh_dir,
            mesh_paths,
            constraints,
            mesh_files,
            quick,
            seed,
            machine,
            progress: MultiProgress::new(),
        })
    }

    /// `results/<name>/`, created if missing.
    pub fn dir(&self, name: &str) -> Result<PathBuf, AnyError> {
        let d = self.out.join(name);
        std::fs::create_dir_all(&d)?;
        Ok(d)
    }

    /// A progress bar of `len` steps with a message.
    pub fn bar(&self, len: usize, message: &str) -> ProgressBar {
        let bar = self.progress.add(ProgressBar::new(len as u64));
        if let Ok(style) = ProgressStyle::with_template(
            "{bar:30.cyan/blue} {pos:>3}/{len:3} {msg} ({elapsed}, eta {eta})",
        ) {
            bar.set_style(style);
        }
        bar.set_message(message.to_string());
        bar.enable_steady_tick(Duration::from_millis(200));
        bar
    }

    /// `true` when the user named meshes (`--mesh`, `--mesh-dir`): the
    /// experiments then run on those instead of generated ones.
    pub fn has_user_meshes(&self) -> bool {
        !self.mesh_files.is_empty()
    }

    /// The command-line arguments that select this run's meshes, for the
    /// "regenerate" lines of the sections (empty for generated meshes).
    pub fn mesh_args(&self) -> String {
        let mut s = String::new();
        for m in &self.mesh_paths {
            let _ = write!(s, " --mesh {}", m.display());
        }
        if let Some(d) = &self.mesh_dir {
            let _ = write!(s, " --mesh-dir {}", d.display());
        }
        s
    }

    /// The user's mesh file whose name (see [`mesh_stem`]) is that of
    /// `file` (e.g. `"bunny-35k-stanford.obj"`), if any.
    pub fn mesh_file(&self, file: &str) -> Option<&Path> {
        let wanted = mesh_stem(Path::new(file));
        self.mesh_files
            .iter()
            .find(|p| mesh_stem(p) == wanted)
            .map(PathBuf::as_path)
    }

    /// Loads the user's mesh named like `file` (see [`Context::mesh_file`]);
    /// `None` without user meshes or if there is no such mesh.
    pub fn real_mesh(&self, file: &str) -> Result<Option<MeshCase>, AnyError> {
        match self.mesh_file(file) {
            Some(path) => load_case(path).map(Some),
            None => Ok(None),
        }
    }

    /// The mesh of a single-mesh experiment: the user's mesh named like
    /// `preferred` if there is one, else the user's first mesh (in the
    /// order of [`Context::mesh_files`]); `None` without user meshes.
    pub fn main_mesh(&self, preferred: &str) -> Result<Option<MeshCase>, AnyError> {
        if let Some(case) = self.real_mesh(preferred)? {
            return Ok(Some(case));
        }
        match self.mesh_files.first() {
            Some(path) => load_case(path).map(Some),
            None => Ok(None),
        }
    }

    /// Every user mesh, loaded, in the order of [`Context::mesh_files`].
    pub fn user_meshes(&self) -> Result<Vec<MeshCase>, AnyError> {
        self.mesh_files.iter().map(|p| load_case(p)).collect()
    }

    /// The meshes of the evaluation: every user mesh (`--mesh`, every mesh
    /// file of `--mesh-dir`); without, generated stand-ins (a bumpy
    /// sphere, the paper's Fig. 1 unsymmetric grid and its Fig. 2 sliver
    /// mesh).
    pub fn evaluation_meshes(&self) -> Result<Vec<MeshCase>, AnyError> {
        if self.has_user_meshes() {
            return self.user_meshes();
        }
        self.generated_evaluation_meshes()
    }

    /// The generated stand-ins of [`Context::evaluation_meshes`].
    pub fn generated_evaluation_meshes(&self) -> Result<Vec<MeshCase>, AnyError> {
        let size = if self.quick { 1_500 } else { 10_000 };
        let mut cases = Vec::new();
        for (name, kind) in [
            ("bumpy-sphere", generate::GeneratedKind::BumpySphere),
            ("unsymmetric-grid", generate::GeneratedKind::UnsymmetricGrid),
            ("sliver", generate::GeneratedKind::Sliver),
        ] {
            cases.push(self.generated(name, kind, size)?);
        }
        Ok(cases)
    }

    /// The mesh of a single-mesh experiment: the user's mesh named like
    /// `preferred` (e.g. `"bunny-35k-stanford.obj"`), else the user's first
    /// mesh, else a generated bumpy sphere of about `vertices` vertices
    /// (`quick_vertices` with `--quick`).
    pub fn fallback_mesh(
        &self,
        preferred: &str,
        vertices: usize,
        quick_vertices: usize,
    ) -> Result<MeshCase, AnyError> {
        if let Some(case) = self.main_mesh(preferred)? {
            return Ok(case);
        }
        let size = if self.quick { quick_vertices } else { vertices };
        self.generated("bumpy-sphere", generate::GeneratedKind::BumpySphere, size)
    }

    /// A generated mesh of about `vertices` vertices, named `name`.
    pub fn generated(
        &self,
        name: &str,
        kind: generate::GeneratedKind,
        vertices: usize,
    ) -> Result<MeshCase, AnyError> {
        let mesh = generate::with_about_vertices(kind, vertices, self.seed)?;
        Ok(MeshCase {
            name: name.into(),
            source: format!(
                "generated {kind}, {} vertices, seed {}",
                mesh.n_vertices(),
                self.seed
            ),
            mesh,
        })
    }

    /// Writes serialisable rows as `stem.csv` (a `#` machine line, a header
    /// from the field names, one line a row; `None` an empty cell) and as
    /// `stem.json` (`{"machine": …, "data": [rows]}`). The rows must be
    /// flat structs (no nested structs or sequences: CSV has no place for
    /// them).
    pub fn write_rows<T: Serialize>(&self, stem: &Path, rows: &[T]) -> Result<(), AnyError> {
        let mut w = csv::WriterBuilder::new().from_writer(Vec::new());
        for r in rows {
            w.serialize(r)?;
        }
        let body = w.into_inner().map_err(|e| e.to_string())?;
        let mut s = format!("# {}\n", self.machine.one_line());
        s.push_str(std::str::from_utf8(&body)?);
        std::fs::write(stem.with_extension("csv"), s)?;
        self.write_json(&stem.with_extension("json"), &rows)
    }

    /// The "Regenerate this section alone" block of a section: the command
    /// with this run's meshes and `--out results`.
    pub fn regenerate(&self, name: &str) -> String {
        format!(
            "Regenerate this section alone:\n\n```sh\ncargo run --release --features suitesparse,mumps --bin experiments -- {name}{} --out results\n```\n\n",
            self.mesh_args()
        )
    }

    /// The end of a section: the notes (what did not work), the sentence
    /// naming the data files and the machine line.
    pub fn closing(&self, notes: &[String], data: &str) -> String {
        let mut s = String::new();
        if !notes.is_empty() {
            s.push_str("\n**What did not work / notes.**\n\n");
            for n in notes {
                let _ = writeln!(s, "- {n}");
            }
        }
        let _ = writeln!(s, "\n{data}\n\n_{}_", self.machine.one_line());
        s
    }

    /// Writes a CSV file whose first line is a `#` comment with the machine
    /// description (`pandas.read_csv(path, comment="#")` reads it).
    pub fn write_csv(
        &self,
        path: &Path,
        header: &[&str],
        rows: &[Vec<String>],
    ) -> Result<(), AnyError> {
        let mut s = format!("# {}\n", self.machine.one_line());
        s.push_str(&header.join(","));
        s.push('\n');
        for row in rows {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    if c.contains([',', '"', '\n']) {
                        format!("\"{}\"", c.replace('"', "\"\""))
                    } else {
                        c.clone()
                    }
                })
                .collect();
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        std::fs::write(path, s)?;
        Ok(())
    }

    /// Writes `{"machine": …, "data": value}` as pretty JSON.
    pub fn write_json(&self, path: &Path, value: &impl Serialize) -> Result<(), AnyError> {
        let doc = serde_json::json!({ "machine": self.machine, "data": value });
        std::fs::write(path, serde_json::to_string_pretty(&doc)? + "\n")?;
        Ok(())
    }

    /// Writes the experiment's section of `results/README.md`
    /// (`results/<name>/section.md`); [`assemble_readme`] joins them.
    pub fn write_section(&self, name: &str, markdown: &str) -> Result<(), AnyError> {
        let path = self.dir(name)?.join("section.md");
        std::fs::write(path, markdown)?;
        Ok(())
    }

    /// Writes `results/<name>/README.md`: the section as the folder's own
    /// page (`# title`, then the section with its links `name/FILE` made
    /// relative to the folder), so that nothing in the folder is written
    /// by hand.
    pub fn write_page(&self, name: &str, title: &str, markdown: &str) -> Result<(), AnyError> {
        let page = format!(
            "# {title}\n\n{}",
            markdown.replace(&format!("]({name}/"), "](")
        );
        std::fs::write(self.dir(name)?.join("README.md"), page)?;
        Ok(())
    }
}

/// The mesh file extensions the experiments read (each also with `.gz`).
pub const MESH_EXTENSIONS: [&str; 3] = ["obj", "ply", "off"];

/// `true` if the file name ends in a mesh extension, optionally `.gz`
/// (case-insensitive).
pub fn is_mesh_file(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    MESH_EXTENSIONS
        .iter()
        .any(|ext| name.len() > ext.len() + 1 && name.ends_with(&format!(".{ext}")))
}

/// The name the experiments give a mesh file: its file name without `.gz`
/// and without the mesh extension (`igea-537k-subdiv.obj.gz` →
/// `igea-537k-subdiv`).
pub fn mesh_stem(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let name = name
        .strip_suffix(".gz")
        .or_else(|| name.strip_suffix(".GZ"))
        .unwrap_or(&name);
    match name.rsplit_once('.') {
        Some((stem, _)) if !stem.is_empty() => stem.to_string(),
        _ => name.to_string(),
    }
}

/// The mesh files directly inside `dir`, sorted by file name.
pub fn mesh_files_in(dir: &Path) -> Result<Vec<PathBuf>, AnyError> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| format!("--mesh-dir {}: cannot list it: {e}", dir.display()))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| format!("--mesh-dir {}: cannot list it: {e}", dir.display()))?
            .path();
        if path.is_file() && is_mesh_file(&path) {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// Loads a mesh file as a case named by its [`mesh_stem`].
fn load_case(path: &Path) -> Result<MeshCase, AnyError> {
    let mesh = read_mesh(path, lse_deform::limits::MemoryBudget::default())
        .map_err(|e| format!("{}: {e}", path.display()))?
        .mesh;
    Ok(MeshCase {
        name: mesh_stem(path),
        mesh,
        source: path.display().to_string(),
    })
}

/// The machine line's description of the user's meshes.
fn mesh_description(paths: &[PathBuf], dir: Option<&Path>) -> Option<String> {
    let mut parts: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    if let Some(d) = dir {
        parts.push(d.display().to_string());
    }
    (!parts.is_empty()).then(|| parts.join(", "))
}

/// A fresh output directory for a run of `experiment`:
/// `target/experiments/<experiment>-<UTC date>-<time>`.
pub fn fresh_out_dir(experiment: &str) -> PathBuf {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (days, rest) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    PathBuf::from("target").join("experiments").join(format!(
        "{experiment}-{year:04}{month:02}{day:02}-{:02}{:02}{:02}",
        rest / 3600,
        rest / 60 % 60,
        rest % 60
    ))
}
