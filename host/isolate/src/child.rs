//! The worker's side: take the channel the parent set up on fixed descriptors, move the
//! in-flight table into the shared page, read the limits and the token, then answer requests
//! until told to stop. A worker always ends with `_exit`: no `atexit` handler or destructor of
//! a law runs at its end, and its libraries are never unloaded (its threads may still run).

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::FromRawFd;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use serde::de::DeserializeOwned;
use serde::Serialize;
use tribo_plugin_api::loader::inflight;

use crate::frame::{self, Kind};
use crate::terms::{Limits, Reply};
use crate::{guard, sys};

/// The worker's end of the request/reply socket.
pub(crate) const CHANNEL_FD: i32 = 3;
/// The write end of the marker pipe.
pub(crate) const MARKER_FD: i32 = 4;
/// The shared page (absent where the system has no memfd).
pub(crate) const SHARED_FD: i32 = 5;

/// The page parent and worker share: the worker's in-flight table and its progress.
#[repr(C)]
pub(crate) struct Shared {
    pub(crate) table: inflight::Table,
    pub(crate) progress: AtomicU64,
}

/// Bytes of the shared page (whole pages).
pub(crate) const SHARED_LEN: usize = std::mem::size_of::<Shared>().div_ceil(4096) * 4096;

/// What a request's handler can do besides answering: stream output and report progress.
pub struct Session {
    writer: Mutex<File>,
    token: [u8; 16],
    progress: Option<&'static AtomicU64>,
}

impl Session {
    /// Send a chunk of streamed output (a time series) to the parent, before the reply.
    pub fn data(&self, bytes: &[u8]) -> std::io::Result<()> {
        self.send(Kind::Data, bytes)
    }

    /// Publish the job's progress position (the parent shows it).
    pub fn progress(&self, position: u64) {
        if let Some(p) = self.progress {
            p.store(position, Ordering::Relaxed);
        }
    }

    fn send(&self, kind: Kind, payload: &[u8]) -> std::io::Result<()> {
        let bytes = frame::encode(&self.token, kind, payload);
        let mut w = self.writer.lock().unwrap_or_else(|p| p.into_inner());
        w.write_all(&bytes)?;
        w.flush()
    }
}

/// Be a worker: answer each request (`Q`) the parent sends with `handler`'s result (`A`) or its
/// error message, until the parent says it is done; then end the process. A panic in the
/// handler is answered as tribo's internal error. Never returns.
pub fn serve<Q, A>(mut handler: impl FnMut(Q, &Session) -> Result<A, String>) -> !
where
    Q: DeserializeOwned,
    A: Serialize,
{
    for fd in [CHANNEL_FD, MARKER_FD, SHARED_FD] {
        // A program a law starts does not inherit the channel.
        sys::set_cloexec(fd);
    }
    let _ = sys::set_nonblocking(MARKER_FD);
    let progress = map_shared();
    // SAFETY: descriptor 3 was set up by the parent for this process and is used only here.
    let mut reader = unsafe { File::from_raw_fd(CHANNEL_FD) };
    let Some((token, hello)) = read_frame(&mut reader, None) else {
        guard::stop(1)
    };
    let limits: Limits = match rmp_serde::from_slice(&hello.1) {
        Ok(l) if hello.0 == Kind::Hello => l,
        _ => guard::stop(1),
    };
    guard::become_worker(limits, &token, MARKER_FD);
    inflight::set_register_hook(|id, text| {
        guard::marker("name", &format!("{} {text}", id.number()));
    });
    let Ok(writer) = reader.try_clone() else {
        guard::stop(1)
    };
    let session = Session {
        writer: Mutex::new(writer),
        token,
        progress,
    };
    while let Some((_, (kind, payload))) = read_frame(&mut reader, Some(&token)) {
        match kind {
            Kind::Confirm => {
                if session.send(Kind::Ack, &payload).is_err() {
                    break;
                }
                continue;
            }
            Kind::Job if payload.len() >= frame::NONCE => {}
            _ => break,
        }
        let (nonce, payload) = payload.split_at(frame::NONCE);
        guard::job_started();
        let reply = match rmp_serde::from_slice::<Q>(payload) {
            Err(e) => Reply::Internal(format!("reading the job: {e}")),
            Ok(q) => match std::panic::catch_unwind(AssertUnwindSafe(|| handler(q, &session))) {
                Ok(Ok(a)) => Reply::Ok(a),
                Ok(Err(message)) => Reply::Err(message),
                Err(_) => {
                    Reply::Internal(guard::take_panic().unwrap_or_else(|| "tribo panicked".into()))
                }
            },
        };
        guard::job_finished();
        let bytes = match rmp_serde::to_vec_named(&reply) {
            Ok(b) => b,
            Err(e) => match rmp_serde::to_vec_named(&Reply::<A>::Internal(format!(
                "encoding the reply: {e}"
            ))) {
                Ok(b) => b,
                Err(_) => guard::stop(1),
            },
        };
        let mut answer = Vec::with_capacity(frame::NONCE + bytes.len());
        answer.extend_from_slice(nonce);
        answer.extend_from_slice(&bytes);
        if session.send(Kind::Reply, &answer).is_err() {
            break;
        }
    }
    guard::allow_exit();
    guard::stop(0)
}

/// Map the shared page, move the in-flight table into it and return its progress word.
fn map_shared() -> Option<&'static AtomicU64> {
    let ptr = sys::map_shared(SHARED_FD, SHARED_LEN).ok()?;
    let shared = ptr.cast::<Shared>();
    // SAFETY: the page is SHARED_LEN zeroed bytes, page-aligned, mapped for the rest of the
    // process (never unmapped), and no plugin code has run in this process yet.
    unsafe {
        inflight::use_shared_table(std::ptr::addr_of_mut!((*shared).table));
        Some(&*std::ptr::addr_of!((*shared).progress))
    }
}

/// A frame read: its token, and its kind and payload.
type Frame = ([u8; 16], (Kind, Vec<u8>));

/// Read one frame. With `token`, a frame must carry it; `None` at end of file or on anything
/// that is not a frame.
fn read_frame(r: &mut File, token: Option<&[u8; 16]>) -> Option<Frame> {
    let mut header = [0u8; frame::HEADER];
    r.read_exact(&mut header).ok()?;
    let mut t = [0u8; 16];
    t.copy_from_slice(&header[4..20]);
    let expect = token.copied().unwrap_or(t);
    if frame::parse(&header, &expect) == frame::Parsed::Forged {
        return None;
    }
    let (kind, len) = frame::header_fields(&header)?;
    let mut payload = Vec::new();
    payload.try_reserve_exact(len).ok()?;
    payload.resize(len, 0);
    r.read_exact(&mut payload).ok()?;
    Some((t, (kind, payload)))
}
