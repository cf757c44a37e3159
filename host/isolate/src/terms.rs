//! The terms of a job in a worker: the limits it runs under, the reply that ends it, and the
//! ways it can fail, with the words that name them. Below the worker's two sides (`parent`,
//! `child`) and the guards, which all use them; the crate root re-exports them.

use std::time::Duration;

use serde::{Deserialize, Serialize};

/// The default wall-time limit of one worker process (a whole run or law set), s.
pub const DEFAULT_TIME_LIMIT_S: f64 = 1800.0;
/// The default resident-memory limit of one worker process, MiB.
pub const DEFAULT_MEMORY_LIMIT_MB: u64 = 4096;
/// The default limit of one law call, s: a friction law answers in nanoseconds to
/// microseconds, so ten seconds inside one call is a law that hangs, not one that is slow.
pub const DEFAULT_CALL_LIMIT_S: f64 = 10.0;
/// The largest time limit accepted (for the run and for one call), s: about 11.6 days.
pub const MAX_TIME_S: f64 = 1e6;
/// The largest memory limit accepted, MiB (16 TiB).
pub const MAX_MEMORY_MB: u64 = 1 << 24;

/// The limits of one worker process (and of a command run in process).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Wall time of the whole job, s (0: none).
    pub time_s: f64,
    /// Resident memory, MiB (0: none).
    pub memory_mb: u64,
    /// Time inside one law call, s (0: none).
    pub call_s: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            time_s: DEFAULT_TIME_LIMIT_S,
            memory_mb: DEFAULT_MEMORY_LIMIT_MB,
            call_s: DEFAULT_CALL_LIMIT_S,
        }
    }
}

/// A limit given out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{option}: {message}")]
pub struct LimitError {
    /// The option (`--time-limit-s`, `time_limit_s`, ...).
    pub option: String,
    /// What is wrong, with the range.
    pub message: String,
}

impl Limits {
    /// The limits, each checked against its range; `names` are the options as the caller
    /// spells them (time, memory, call), for the message.
    pub fn checked(self, names: [&str; 3]) -> Result<Self, LimitError> {
        seconds(names[0], self.time_s)?;
        if self.memory_mb > MAX_MEMORY_MB {
            return Err(LimitError {
                option: names[1].into(),
                message: format!(
                    "expected a number of MiB from 0 (no limit) to {MAX_MEMORY_MB} (16 TiB), got {}",
                    self.memory_mb
                ),
            });
        }
        seconds(names[2], self.call_s)?;
        Ok(self)
    }

    /// The wall-time limit, if any.
    pub fn time(&self) -> Option<Duration> {
        duration(self.time_s)
    }

    /// The limit of one law call, if any.
    pub fn call(&self) -> Option<Duration> {
        duration(self.call_s)
    }
}

fn duration(s: f64) -> Option<Duration> {
    (s > 0.0)
        .then(|| Duration::try_from_secs_f64(s.min(MAX_TIME_S)).ok())
        .flatten()
}

/// Check a number of seconds for a limit option: finite, from 0 (none) to [`MAX_TIME_S`].
pub fn seconds(option: &str, s: f64) -> Result<f64, LimitError> {
    if s.is_finite() && (0.0..=MAX_TIME_S).contains(&s) {
        Ok(s)
    } else {
        Err(LimitError {
            option: option.into(),
            message: format!(
                "expected a number of seconds from 0 (no limit) to {MAX_TIME_S:e} (about 11.6 days), got {}",
                show(s)
            ),
        })
    }
}

/// A number as a person reads it: `1e300`, not three hundred digits.
fn show(x: f64) -> String {
    if x.is_finite() && x != 0.0 && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Why a worker gave no result.
#[derive(Debug, Clone, thiserror::Error)]
pub enum WorkerFailure {
    /// The job itself failed; the message is the one an in-process run prints.
    #[error("{0}")]
    Study(String),
    /// Killed by a signal (a crash, an abort, a kill from a law or from outside).
    #[error("the worker process running it was killed by signal {signal} ({}){}{}", signal_name(*signal), running_text(running), last_words_text(last_words))]
    Signal {
        /// Signal number.
        signal: i32,
        /// The plugin code running when it happened.
        running: Vec<String>,
        /// The worker's last line on standard error, if any.
        last_words: Option<String>,
    },
    /// Stopped by a signal (SIGSTOP from a law or from outside): it would never answer.
    #[error("the worker process running it was stopped by signal {signal} ({}){}; it was ended", signal_name(*signal), running_text(running))]
    Stopped {
        /// Signal number.
        signal: i32,
        /// The plugin code running then.
        running: Vec<String>,
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
    /// The worker ended without a reply and without a word (a law's `_exit`, say).
    #[error(
        "the worker process ended with status {code} without sending results{}{}",
        running_text(running),
        last_words_text(last_words)
    )]
    NoReply {
        /// Exit status.
        code: i32,
        /// The plugin code running when it ended.
        running: Vec<String>,
        /// Its last line on standard error.
        last_words: Option<String>,
    },
    /// The wall-time limit ran out.
    #[error("stopped after the time limit of {limit_s} s{}; raise it with --time-limit-s if it is only slow", running_text(running))]
    TimeLimit {
        /// The limit, s.
        limit_s: f64,
        /// The plugin code running then.
        running: Vec<String>,
    },
    /// One law call ran past the call limit; the text names the law, its joint and the
    /// call's inputs.
    #[error("{text}")]
    CallLimit {
        /// What the watchdog said.
        text: String,
    },
    /// The memory limit was exceeded.
    #[error("stopped at {resident_mb} MiB of memory, over the limit of {limit_mb} MiB{}; raise it with --memory-limit-mb if it really needs more", running_text(running))]
    MemoryLimit {
        /// The limit, MiB.
        limit_mb: u64,
        /// The resident size seen, MiB.
        resident_mb: u64,
        /// The plugin code running then.
        running: Vec<String>,
    },
    /// The channel carried bytes the worker did not write with the job's token.
    #[error("the worker's reply channel carried data tribo did not write{} (a law wrote into it); its results are not trusted", running_text(running))]
    Forged {
        /// The plugin code running when the bytes came.
        running: Vec<String>,
    },
    /// A law of the task, or a process it started, made entries in the result folder while
    /// the laws ran (tribo writes there only after every law has finished).
    #[error("a law of this set, or a process it started, wrote {} into the result folder {dir} while the laws ran (tribo writes there only after every law has finished; what was written is removed){}; the laws loaded: {}", entries_text(entries), if *uncertain { " (another set ran at the same time, and running each again alone did not repeat it: tribo cannot tell which of them did it, so each is failed)" } else { "" }, if laws.is_empty() { "none".to_string() } else { laws.join(", ") })]
    Planted {
        /// The entries made.
        entries: Vec<String>,
        /// The result folder.
        dir: String,
        /// The laws the worker had loaded.
        laws: Vec<String>,
        /// Charged to every set that ran at the same time (the maker could not be told).
        uncertain: bool,
    },
    /// Tribo itself failed inside the worker (a bug, not the law's fault).
    #[error("internal error in the worker process: {0}; this is a bug in tribo, not in a law: please report it")]
    Internal(String),
    /// The caller asked to stop (Ctrl-C in Python).
    #[error("interrupted")]
    Interrupted,
    /// The worker could not be started or talked to.
    #[error("could not run a worker process: {0}")]
    Io(String),
}

/// How a failure's `running` list says that no law call was under way, followed by the laws
/// the worker had loaded (one of them, through a thread or a child it started, may be the
/// culprit).
pub(crate) const NO_CALL_PREFIX: &str = "\u{0}no call; loaded: ";

fn running_text(running: &[String]) -> String {
    match running.first().and_then(|r| r.strip_prefix(NO_CALL_PREFIX)) {
        Some(laws) => format!(
            " while no law call was under way; the laws loaded in it were {laws} (a thread or a process one of them started may have done it)"
        ),
        None if running.is_empty() => {
            " while no law was running (in tribo itself, or between law calls)".into()
        }
        None => format!(" while running {}", running.join(" and ")),
    }
}

/// Up to five entry names, quoted, and how many more.
fn entries_text(entries: &[String]) -> String {
    let shown: Vec<String> = entries.iter().take(5).map(|n| format!("`{n}`")).collect();
    let more = entries.len().saturating_sub(5);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

fn last_words_text(last: &Option<String>) -> String {
    last.as_ref()
        .map(|l| format!("; its last words: \"{l}\""))
        .unwrap_or_default()
}

/// The name and meaning of the signals a law can end or stop a process with.
pub fn signal_name(signal: i32) -> &'static str {
    match signal {
        1 => "SIGHUP, hung up",
        2 => "SIGINT, interrupted",
        4 => "SIGILL, illegal instruction",
        6 => "SIGABRT, the process aborted",
        7 => "SIGBUS, bad memory access",
        8 => "SIGFPE, arithmetic fault",
        9 => "SIGKILL, killed from outside or by the out-of-memory killer",
        11 => "SIGSEGV, invalid memory access",
        13 => "SIGPIPE, wrote to a closed pipe",
        15 => "SIGTERM, terminated",
        19 => "SIGSTOP, stopped",
        20 => "SIGTSTP, stopped from a terminal",
        21 | 22 => "SIGTTIN/SIGTTOU, stopped for terminal input or output",
        25 => "SIGXFSZ, file size limit",
        _ => "a signal",
    }
}

/// What a worker hands back for one request.
#[derive(Debug, Serialize, Deserialize)]
pub enum Reply<T> {
    /// The job ran.
    Ok(T),
    /// The job failed with this message (a law error, a non-converging run, ...).
    Err(String),
    /// Tribo itself panicked in the worker (a bug).
    Internal(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_out_of_range_are_refused_naming_the_option() {
        let names = ["--time-limit-s", "--memory-limit-mb", "--call-limit-s"];
        assert!(Limits::default().checked(names).is_ok());
        for bad in [1e300, -1.0, f64::NAN, f64::INFINITY] {
            let e = Limits {
                time_s: bad,
                ..Limits::default()
            }
            .checked(names)
            .expect_err("refused");
            assert_eq!(e.option, "--time-limit-s");
            let e = Limits {
                call_s: bad,
                ..Limits::default()
            }
            .checked(names)
            .expect_err("refused");
            assert_eq!(e.option, "--call-limit-s");
        }
        let e = Limits {
            memory_mb: u64::MAX,
            ..Limits::default()
        }
        .checked(names)
        .expect_err("refused");
        assert!(e.to_string().contains("--memory-limit-mb"), "{e}");
        assert_eq!(
            Limits {
                time_s: 0.0,
                ..Limits::default()
            }
            .time(),
            None
        );
    }
}
