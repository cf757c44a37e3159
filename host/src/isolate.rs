//! Law plugins in worker processes, for the `tribo` command: the worker protocol, guards and
//! limits of [`tribo_isolate`], with the command that starts a worker (`tribo` itself, hidden
//! subcommand [`WORKER_SUBCOMMAND`]) and what the command line does with a worker's events.
//!
//! Every command that runs laws (`run`, `compare`, `fit`, `mass-response`, `sweep`,
//! `check-law`, `plot-law`) runs them in workers unless given `--in-process`; the `tribo`
//! process itself never opens a plugin library then. This is fault isolation, not a security
//! sandbox: a worker runs with the user's rights (docs/reliability.md, "Trust model").

use std::path::PathBuf;
use std::process::Command;

pub use tribo_isolate::*;

/// The hidden subcommand a worker process runs: `tribo __worker` (the job arrives on its
/// channel, never on the command line).
pub const WORKER_SUBCOMMAND: &str = "__worker";

/// The command that starts a worker: this `tribo` executable with the plugin search path of
/// the parent (`--plugin`), quiet.
pub fn worker_command(plugins: &[PathBuf]) -> Command {
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("tribo"));
    let mut cmd = Command::new(exe);
    cmd.arg("--quiet");
    for p in plugins {
        cmd.arg("--plugin").arg(p);
    }
    cmd.arg(WORKER_SUBCOMMAND);
    cmd
}

/// What the command line does with a worker's events: standard-error lines forwarded (each
/// warning once), notes of slow law calls printed with `label` (which law set or run).
pub fn show_event(label: &str, event: &Event<'_>) {
    match event {
        Event::Stderr(line) => forward_stderr(line),
        Event::Slow(note) => {
            use std::io::Write as _;
            let _ = writeln!(std::io::stderr(), "note: {label}{note}");
        }
        _ => {}
    }
}
