//! `lse-deform edit MESH`: the interactive editor's server.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use lse_deform::Error;
use lse_deform::error::ProblemError;

/// Arguments of `edit`.
#[derive(Args)]
pub struct EditArgs {
    /// Input mesh.
    mesh: PathBuf,
    /// Constraints file (JSON) to start with.
    #[arg(long, short = 'c')]
    constraints: Option<PathBuf>,
    /// Address to bind (anything but a loopback address prints a warning:
    /// plain HTTP carries the token unencrypted).
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Port (0: any free port; the first line on stdout says which).
    #[arg(long, default_value_t = 0)]
    port: u16,
    /// Cap on request bodies in bytes (413 beyond).
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_MAX_BODY_BYTES)]
    max_body_bytes: usize,
    /// The session token that every API request must carry (16 to 256
    /// characters of A-Z a-z 0-9 - . _ ~); by default 32 random bytes in
    /// hex. Prefer the environment variable: a command line is visible to
    /// other users.
    #[arg(long, env = lse_deform::editor::TOKEN_ENV, hide_env_values = true)]
    token: Option<String>,
    /// Seconds a request body has to arrive after its head (408 beyond).
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_BODY_TIMEOUT.as_secs_f64())]
    body_timeout: f64,
    /// Seconds a connection may stay idle, or take to send a request head,
    /// before it is closed.
    #[arg(long, default_value_t = lse_deform::editor::DEFAULT_IDLE_TIMEOUT.as_secs_f64())]
    idle_timeout: f64,
}

/// Runs the editor's server until it is stopped.
pub(crate) fn edit(a: EditArgs) -> Result<(), Error> {
    let seconds = |name: &str, s: f64| {
        if s.is_finite() && s > 0.0 && s <= 1e6 {
            Ok(Duration::from_secs_f64(s))
        } else {
            Err(Error::from(ProblemError::InvalidArgument {
                message: format!("{name} {s} must be a positive number of seconds (at most 1e6)"),
            }))
        }
    };
    lse_deform::editor::run(lse_deform::editor::EditOptions {
        mesh: a.mesh,
        constraints: a.constraints,
        host: a.host,
        port: a.port,
        max_body_bytes: a.max_body_bytes,
        token: a.token,
        body_timeout: seconds("--body-timeout", a.body_timeout)?,
        idle_timeout: seconds("--idle-timeout", a.idle_timeout)?,
    })
}
