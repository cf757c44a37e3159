//! The messages of the worker channel: every one tagged with the job's random token, so bytes a
//! law writes into the channel (it runs in the worker's process and can write to any of its
//! descriptors) are told apart from the worker's own messages and fail the job as forged
//! instead of being believed.
//!
//! A frame is `MAGIC`, the 16-byte token, a kind byte, the payload length (u32, little endian)
//! and the payload (MessagePack). Markers, the short reports a worker's guards write from
//! signal handlers and hooks, travel on their own pipe as text lines, each one `write(2)` of at
//! most `MARKER_MAX` bytes (atomic on a pipe), starting with the token in hex.
//!
//! Each request carries a fresh random nonce (`NONCE` bytes before its payload) that its reply
//! must repeat, and a reply is believed only once the worker has echoed a second nonce sent
//! after it (`Confirm`, `Ack`): a reply written by a law (which runs in the worker and can
//! read its memory) does not count unless the worker is alive and answering afterwards.

/// First bytes of every frame.
pub(crate) const MAGIC: [u8; 4] = *b"TRBw";
/// Bytes before the payload.
pub(crate) const HEADER: usize = 4 + 16 + 1 + 4;
/// Largest payload accepted (a study's reply is megabytes at most).
pub(crate) const MAX_PAYLOAD: usize = 1 << 30;
/// Bytes of a request's nonce (before the payload of a `Job`, a `Reply` and a `Confirm`).
pub(crate) const NONCE: usize = 16;
/// Longest marker line, bytes (below PIPE_BUF, so one write is never interleaved).
pub(crate) const MARKER_MAX: usize = 4000;

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Kind {
    /// Parent to worker, first: the limits (the token is in the header).
    Hello = 1,
    /// Parent to worker: a request.
    Job = 2,
    /// Parent to worker: no more requests; end.
    Bye = 3,
    /// Parent to worker, after a reply: a fresh nonce the worker must echo (`Ack`) before the
    /// reply is believed, so a reply forged by a law that then died is never accepted.
    Confirm = 4,
    /// Worker to parent: the answer to the last request.
    Reply = 10,
    /// Worker to parent: a chunk of streamed output (a time series) before the reply.
    Data = 11,
    /// Worker to parent: the echo of a `Confirm`.
    Ack = 12,
}

impl Kind {
    fn from_u8(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::Hello,
            2 => Self::Job,
            3 => Self::Bye,
            4 => Self::Confirm,
            10 => Self::Reply,
            11 => Self::Data,
            12 => Self::Ack,
            _ => return None,
        })
    }
}

/// One frame's bytes.
pub(crate) fn encode(token: &[u8; 16], kind: Kind, payload: &[u8]) -> Vec<u8> {
    let mut v = Vec::with_capacity(HEADER + payload.len());
    v.extend_from_slice(&MAGIC);
    v.extend_from_slice(token);
    v.push(kind as u8);
    v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    v.extend_from_slice(payload);
    v
}

/// What the start of a buffer holds.
#[derive(Debug, PartialEq)]
pub(crate) enum Parsed {
    /// Not a whole frame yet.
    Partial,
    /// A frame of `kind` whose payload is `buf[HEADER..HEADER + len]`.
    Frame { kind: Kind, len: usize },
    /// Bytes that are no frame of this job: a wrong magic, token, kind or length.
    Forged,
}

/// Parse the frame at the start of `buf` for `token`.
pub(crate) fn parse(buf: &[u8], token: &[u8; 16]) -> Parsed {
    let have = buf.len().min(HEADER);
    // Judge the bytes already there: a forgery is found without waiting for more.
    if buf[..have.min(4)] != MAGIC[..have.min(4)] {
        return Parsed::Forged;
    }
    if have > 4 && buf[4..have.min(20)] != token[..have.min(20) - 4] {
        return Parsed::Forged;
    }
    if have < HEADER {
        return Parsed::Partial;
    }
    let Some(kind) = Kind::from_u8(buf[20]) else {
        return Parsed::Forged;
    };
    let len = u32::from_le_bytes([buf[21], buf[22], buf[23], buf[24]]) as usize;
    if len > MAX_PAYLOAD {
        return Parsed::Forged;
    }
    if buf.len() < HEADER + len {
        return Parsed::Partial;
    }
    Parsed::Frame { kind, len }
}

/// The kind and payload length of a whole, valid header.
pub(crate) fn header_fields(header: &[u8]) -> Option<(Kind, usize)> {
    let kind = Kind::from_u8(*header.get(20)?)?;
    let len = u32::from_le_bytes(header.get(21..25)?.try_into().ok()?) as usize;
    (len <= MAX_PAYLOAD).then_some((kind, len))
}

/// The token as 32 lowercase hex digits (how markers start).
pub(crate) fn hex(token: &[u8; 16]) -> [u8; 32] {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = [0u8; 32];
    for (i, b) in token.iter().enumerate() {
        out[2 * i] = DIGITS[(b >> 4) as usize];
        out[2 * i + 1] = DIGITS[(b & 15) as usize];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_round_trips_and_a_wrong_token_or_junk_is_forged() {
        let token = [7u8; 16];
        let f = encode(&token, Kind::Reply, b"hello");
        assert_eq!(
            parse(&f, &token),
            Parsed::Frame {
                kind: Kind::Reply,
                len: 5
            }
        );
        assert_eq!(&f[HEADER..], b"hello");
        for cut in 0..f.len() {
            assert_eq!(parse(&f[..cut], &token), Parsed::Partial, "cut at {cut}");
        }
        assert_eq!(parse(&f, &[8u8; 16]), Parsed::Forged);
        assert_eq!(
            parse(b"\x1ftribo-worker exit called\n", &token),
            Parsed::Forged
        );
        let mut bad_kind = f.clone();
        bad_kind[20] = 99;
        assert_eq!(parse(&bad_kind, &token), Parsed::Forged);
    }

    #[test]
    fn hex_spells_every_byte() {
        let mut t = [0u8; 16];
        t[0] = 0xab;
        t[15] = 0x01;
        let h = hex(&t);
        assert_eq!(&h[..2], b"ab");
        assert_eq!(&h[30..], b"01");
    }
}
