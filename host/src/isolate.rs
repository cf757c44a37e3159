//! Law sets whose plugins are not trusted, run in worker processes: `tribo` starts itself again
//! (hidden subcommand [`WORKER_SUBCOMMAND`]) once per law set, with a wall-time and a memory
//! limit, so a law that crashes, hangs, eats memory or calls `exit()` fails only its own law set,
//! and the message names the law, its library and the signal or limit.
//!
//! The parent writes a job (MessagePack) into a private temporary directory and reads the worker's
//! [`Reply`] from there; the worker's standard output goes nowhere (a law printing to it cannot
//! corrupt results) and its standard error is read for the marker lines [`guard`] writes when it
//! stops the worker. This is fault isolation, not a security sandbox: a worker runs with the
//! user's rights (docs/reliability.md, "Trust model").

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

pub mod guard;

/// The hidden subcommand a worker process runs: `tribo __worker JOB.json REPLY.json`.
pub const WORKER_SUBCOMMAND: &str = "__worker";

/// How long the parent waits past the time limit before it kills a worker that did not stop
/// itself (its own watchdog normally ends it first and names the law).
const KILL_GRACE: Duration = Duration::from_secs(5);

/// Keep at most this much of a worker's standard error (its tail) for the failure message.
const STDERR_TAIL_BYTES: usize = 4096;

/// The limits of one worker process.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Wall time, s (0: none).
    pub time_s: f64,
    /// Resident memory, MiB (0: none).
    pub memory_mb: u64,
}

impl Limits {
    /// The wall-time limit, if any.
    pub fn time(&self) -> Option<Duration> {
        (self.time_s > 0.0).then(|| Duration::from_secs_f64(self.time_s))
    }
}

/// What a worker hands back: its result, or the error message the same study would have
/// printed in process.
#[derive(Debug, Serialize, Deserialize)]
pub enum Reply<T> {
    /// The study ran.
    Ok(T),
    /// The study failed with this message (a law error, a non-converging run, ...).
    Err(String),
}

/// The whole job file a worker reads.
#[derive(Debug, Serialize, Deserialize)]
pub struct Job<J> {
    /// The limits the worker enforces on itself.
    pub limits: Limits,
    /// What to run.
    pub work: J,
}

/// Why a worker gave no result.
#[derive(Debug, thiserror::Error)]
pub enum WorkerFailure {
    /// The study itself failed; the message is the one an in-process run prints.
    #[error("{0}")]
    Study(String),
    /// Killed by a signal (a crash, an abort).
    #[error("the worker process running it was killed by signal {signal} ({}){}{}", signal_name(*signal), running_text(running), last_words_text(last_words))]
    Signal {
        /// Signal number.
        signal: i32,
        /// The plugin code running when it happened.
        running: Vec<String>,
        /// The worker's last line on standard error, if any.
        last_words: Option<String>,
    },
    /// A law called `exit()` inside the worker.
    #[error(
        "a law ended the worker process by calling exit(){}; its results were lost",
        running_text(running)
    )]
    PluginExit {
        /// The plugin code running then.
        running: Vec<String>,
    },
    /// The wall-time limit ran out.
    #[error("stopped after the time limit of {limit_s} s{}; raise it with --time-limit-s if the law set is only slow", running_text(running))]
    TimeLimit {
        /// The limit, s.
        limit_s: f64,
        /// The plugin code running then.
        running: Vec<String>,
    },
    /// The memory limit was exceeded.
    #[error("stopped at {resident_mb} MiB of memory, over the limit of {limit_mb} MiB{}; raise it with --memory-limit-mb if the law set really needs more", running_text(running))]
    MemoryLimit {
        /// The limit, MiB.
        limit_mb: u64,
        /// The resident size seen, MiB.
        resident_mb: u64,
        /// The plugin code running then.
        running: Vec<String>,
    },
    /// Ended without a reply and without a reason.
    #[error(
        "the worker process ended with status {code} without results{}",
        last_words_text(last_words)
    )]
    NoReply {
        /// Exit status.
        code: i32,
        /// Its last line on standard error.
        last_words: Option<String>,
    },
    /// The worker could not be started or its files not handled.
    #[error("could not run a worker process: {0}")]
    Io(String),
}

fn running_text(running: &[String]) -> String {
    if running.is_empty() {
        " while no law was running (in tribo itself, or between law calls)".into()
    } else {
        format!(" while running {}", running.join(" and "))
    }
}

fn last_words_text(last: &Option<String>) -> String {
    last.as_ref()
        .map(|l| format!("; its last words: \"{l}\""))
        .unwrap_or_default()
}

/// The name and meaning of the signals a law can end a process with.
pub fn signal_name(signal: i32) -> &'static str {
    match signal {
        4 => "SIGILL, illegal instruction",
        6 => "SIGABRT, the process aborted",
        7 => "SIGBUS, bad memory access",
        8 => "SIGFPE, arithmetic fault",
        9 => "SIGKILL, killed from outside or by the out-of-memory killer",
        11 => "SIGSEGV, invalid memory access",
        15 => "SIGTERM, terminated from outside",
        _ => "a fatal signal",
    }
}

/// Run each task's job in its own worker process (at most as many at once as the machine has
/// cores), returning the results in the order of `tasks`.
pub fn run_all<J, T>(
    tasks: &[J],
    plugins: &[PathBuf],
    limits: Limits,
) -> Result<Vec<Result<T, WorkerFailure>>, WorkerFailure>
where
    J: Serialize + Sync,
    T: DeserializeOwned + Send,
{
    let dir = tempfile::Builder::new()
        .prefix("tribo-workers.")
        .tempdir()
        .map_err(|e| WorkerFailure::Io(format!("creating a temporary directory: {e}")))?;
    let parallel = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(tasks.len().max(1));
    let next = AtomicUsize::new(0);
    let mut results: Vec<Option<Result<T, WorkerFailure>>> =
        (0..tasks.len()).map(|_| None).collect();
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|s| {
        for _ in 0..parallel {
            let tx = tx.clone();
            let next = &next;
            let dir = dir.path();
            s.spawn(move || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(task) = tasks.get(i) else { break };
                let r = run_one(task, i, dir, plugins, limits);
                if tx.send((i, r)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        for (i, r) in rx {
            results[i] = Some(r);
        }
    });
    Ok(results
        .into_iter()
        .map(|r| {
            r.unwrap_or_else(|| Err(WorkerFailure::Io("a worker thread stopped early".into())))
        })
        .collect())
}

/// One worker: write the job, start `tribo __worker`, wait within the limits, read the reply.
fn run_one<J: Serialize, T: DeserializeOwned>(
    work: &J,
    index: usize,
    dir: &Path,
    plugins: &[PathBuf],
    limits: Limits,
) -> Result<T, WorkerFailure> {
    let io = |what: &str, e: &dyn std::fmt::Display| WorkerFailure::Io(format!("{what}: {e}"));
    let job_path = dir.join(format!("job-{index}.json"));
    let reply_path = dir.join(format!("reply-{index}.json"));
    let job = Job { limits, work };
    let text = rmp_serde::to_vec_named(&job).map_err(|e| io("writing the job", &e))?;
    std::fs::write(&job_path, text).map_err(|e| io("writing the job", &e))?;
    let exe = std::env::current_exe().map_err(|e| io("finding the tribo executable", &e))?;
    let mut cmd = Command::new(exe);
    cmd.arg("--quiet");
    for p in plugins {
        cmd.arg("--plugin").arg(p);
    }
    cmd.arg(WORKER_SUBCOMMAND)
        .arg(&job_path)
        .arg(&reply_path)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let mut child = cmd
        .spawn()
        .map_err(|e| io("starting a worker process", &e))?;
    let pid = child.id();
    let mut stderr = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut tail = Vec::new();
        let mut markers = Vec::new();
        if let Some(err) = stderr.as_mut() {
            read_stderr(err, &mut tail, &mut markers);
        }
        (tail, markers)
    });
    let (tx, rx) = mpsc::channel();
    let waiter = std::thread::spawn(move || {
        let _ = tx.send(child.wait());
    });
    let status = match limits.time() {
        Some(t) => match rx.recv_timeout(t + KILL_GRACE) {
            Ok(s) => s,
            Err(_) => {
                guard::kill(pid);
                rx.recv().map_err(|e| io("waiting for a worker", &e))?
            }
        },
        None => rx.recv().map_err(|e| io("waiting for a worker", &e))?,
    }
    .map_err(|e| io("waiting for a worker", &e))?;
    let _ = waiter.join();
    let (tail, markers) = reader.join().unwrap_or_default();
    let reply = std::fs::read(&reply_path).ok();
    interpret(status, reply.as_deref(), &tail, &markers, limits)
}

/// Read a worker's standard error to its end: the marker lines, and the tail of the rest.
fn read_stderr(err: &mut impl Read, tail: &mut Vec<u8>, markers: &mut Vec<String>) {
    let mut buf = [0u8; 8192];
    let mut line = Vec::new();
    loop {
        let n = match err.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            if b == b'\n' {
                let text = String::from_utf8_lossy(&line).into_owned();
                if let Some(m) = text.strip_prefix(guard::MARKER) {
                    markers.push(m.to_string());
                } else {
                    tail.extend_from_slice(&line);
                    tail.push(b'\n');
                    if tail.len() > 2 * STDERR_TAIL_BYTES {
                        tail.drain(..tail.len() - STDERR_TAIL_BYTES);
                    }
                }
                line.clear();
            } else if line.len() < 64 * 1024 {
                line.push(b);
            }
        }
    }
    if !line.is_empty() {
        tail.extend_from_slice(&line);
    }
}

/// Turn a worker's end into its result or the reason it has none.
fn interpret<T: DeserializeOwned>(
    status: ExitStatus,
    reply: Option<&[u8]>,
    tail: &[u8],
    markers: &[String],
    limits: Limits,
) -> Result<T, WorkerFailure> {
    let running: Vec<String> = markers
        .iter()
        .filter_map(|m| m.strip_prefix("running ").map(str::to_string))
        .collect();
    let last_words = String::from_utf8_lossy(tail)
        .lines()
        .map(str::trim)
        .rfind(|l| !l.is_empty())
        .map(|l| l.chars().take(300).collect::<String>());
    if let Some(m) = markers.iter().find_map(|m| m.strip_prefix("limit memory ")) {
        return Err(WorkerFailure::MemoryLimit {
            limit_mb: limits.memory_mb,
            resident_mb: m.trim().parse().unwrap_or(0),
            running,
        });
    }
    if markers.iter().any(|m| m == "limit time") {
        return Err(WorkerFailure::TimeLimit {
            limit_s: limits.time_s,
            running,
        });
    }
    if markers.iter().any(|m| m == "exit called") {
        return Err(WorkerFailure::PluginExit { running });
    }
    if let Some(signal) = guard::signal_of(&status) {
        if signal == 9 && limits.time().is_some() && running.is_empty() {
            // Our own kill after the grace period: the watchdog could not report.
            return Err(WorkerFailure::TimeLimit {
                limit_s: limits.time_s,
                running,
            });
        }
        return Err(WorkerFailure::Signal {
            signal,
            running,
            last_words,
        });
    }
    match reply.map(rmp_serde::from_slice::<Reply<T>>) {
        Some(Ok(Reply::Ok(t))) if status.success() => Ok(t),
        Some(Ok(Reply::Err(message))) => Err(WorkerFailure::Study(message)),
        _ => Err(WorkerFailure::NoReply {
            code: status.code().unwrap_or(-1),
            last_words,
        }),
    }
}

/// In a worker: read the job, set the limits, run `work`, write its reply. Returns whether the
/// study succeeded (the worker's exit status).
pub fn serve<J, T>(
    job_path: &Path,
    reply_path: &Path,
    work: impl FnOnce(J) -> anyhow::Result<T>,
) -> anyhow::Result<bool>
where
    J: DeserializeOwned,
    T: Serialize,
{
    use anyhow::Context;
    let text = std::fs::read(job_path)
        .with_context(|| format!("reading the worker job {}", job_path.display()))?;
    let job: Job<J> = rmp_serde::from_slice(&text)
        .with_context(|| format!("reading the worker job {}", job_path.display()))?;
    guard::become_worker(job.limits);
    let reply = match work(job.work) {
        Ok(t) => Reply::Ok(t),
        Err(e) => Reply::Err(format!("{e:#}")),
    };
    let ok = matches!(reply, Reply::Ok(_));
    let bytes = rmp_serde::to_vec_named(&reply).context("encoding the worker's reply")?;
    std::fs::write(reply_path, bytes)
        .with_context(|| format!("writing the worker reply {}", reply_path.display()))?;
    Ok(ok)
}
