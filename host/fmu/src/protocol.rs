//! What the FMU's library and its worker process say to each other: one request, one reply,
//! each a MessagePack frame (every f64 kept bit for bit) behind its length.

use std::io::{Read, Write};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::stepping::{Inputs, Outputs};

/// A frame longer than this is refused: no request or reply comes near it, so it can only be
/// a corrupted stream.
const MAX_FRAME: usize = 256 << 20;

/// The version of these messages: the FMU's library and its worker must agree on it (a
/// library and a `tribo` from different builds are refused, not misread).
pub const PROTOCOL_VERSION: u32 = 3;

/// What the FMU asks its worker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Request {
    /// Build the run: each law's parameters (TOML text, in the interface's law order), the
    /// inputs, the start time, and the longest a request may take before the worker stops
    /// itself.
    Start {
        /// Parameters per law.
        laws: Vec<String>,
        /// The inputs at the start.
        inputs: Inputs,
        /// Start time, s.
        start_time_s: f64,
        /// The crank speed a torque-driven crank starts turning at, rad/s (the
        /// `crank_speed_start` parameter; unused under a speed input).
        crank_speed_start_rad_s: f64,
        /// The per-request time limit, s.
        timeout_s: f64,
    },
    /// Hold new inputs from the current instant.
    Inputs(Inputs),
    /// New law parameters from the current instant on (law states kept).
    Params(Vec<String>),
    /// Advance to a time with the inputs held.
    Step {
        /// End of the step, s.
        t_end_s: f64,
        /// The inputs over the step.
        inputs: Inputs,
    },
    /// The whole state, for an FMU state.
    Save,
    /// Go back to a saved state.
    Restore(Vec<u8>),
    /// End the worker.
    Quit,
}

/// What the worker answers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// The worker read the FMU's resources and loaded its laws; it speaks this version.
    Ready(u32),
    /// The rig at the current instant, and the cycle means.
    Outputs(Box<Report>),
    /// A saved state.
    State(Vec<u8>),
    /// The request failed: the message says why (the same words `tribo run` would print).
    Error(String),
    /// The worker ends.
    Bye,
}

/// The outputs at a communication point with the means over the last whole cycle.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Report {
    /// The rig at the current instant.
    pub now: Outputs,
    /// The friction torque's mean over the last whole cycle, N m.
    pub friction_torque_cycle_mean_nm: f64,
    /// The drive torque's mean over the last whole cycle, N m.
    pub drive_torque_cycle_mean_nm: f64,
    /// What the run warned of since the last report, each warning once (the library logs
    /// them to the importer with status fmi2Warning).
    pub warnings: Vec<String>,
}

/// Why a frame could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The stream ended cleanly before a frame.
    #[error("the stream ended")]
    Closed,
    /// Reading or writing failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The bytes are not a message.
    #[error("a garbled message ({0})")]
    Garbled(String),
}

/// Write `message` as one frame and flush.
pub fn write_frame<T: Serialize>(out: &mut impl Write, message: &T) -> Result<(), FrameError> {
    let body = rmp_serde::to_vec(message).map_err(|e| FrameError::Garbled(e.to_string()))?;
    let len = u32::try_from(body.len()).map_err(|_| FrameError::Garbled("too long".into()))?;
    out.write_all(&len.to_le_bytes())?;
    out.write_all(&body)?;
    out.flush()?;
    Ok(())
}

/// Read one frame; [`FrameError::Closed`] if the stream ends before it starts.
pub fn read_frame<T: DeserializeOwned>(input: &mut impl Read) -> Result<T, FrameError> {
    let mut len = [0u8; 4];
    let mut got = 0;
    while got < len.len() {
        match input.read(&mut len[got..]) {
            Ok(0) if got == 0 => return Err(FrameError::Closed),
            Ok(0) => return Err(FrameError::Io(std::io::ErrorKind::UnexpectedEof.into())),
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    let len = u32::from_le_bytes(len) as usize;
    if len > MAX_FRAME {
        return Err(FrameError::Garbled(format!("a frame of {len} bytes")));
    }
    let mut body = vec![0u8; len];
    input.read_exact(&mut body)?;
    rmp_serde::from_slice(&body).map_err(|e| FrameError::Garbled(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_carry_every_bit_and_a_closed_stream_is_told_apart() {
        let inputs = Inputs {
            drive: 0.1 + 0.2,
            oil_temperature_c: f64::MIN_POSITIVE,
        };
        let mut buf = Vec::new();
        write_frame(&mut buf, &Request::Inputs(inputs)).expect("write");
        write_frame(&mut buf, &Request::Quit).expect("write");
        let mut r = buf.as_slice();
        let first: Request = read_frame(&mut r).expect("read");
        assert_eq!(first, Request::Inputs(inputs));
        let second: Request = read_frame(&mut r).expect("read");
        assert_eq!(second, Request::Quit);
        assert!(matches!(
            read_frame::<Request>(&mut r),
            Err(FrameError::Closed)
        ));
        // A frame cut short is an error, not a clean end.
        let cut = &buf[..buf.len() - 1];
        let mut r = cut;
        let _: Request = read_frame(&mut r).expect("first frame whole");
        assert!(matches!(
            read_frame::<Request>(&mut r),
            Err(FrameError::Io(_))
        ));
        // Garbage after a plausible length.
        let mut bad = 3u32.to_le_bytes().to_vec();
        bad.extend([0xc1, 0xc1, 0xc1]);
        assert!(matches!(
            read_frame::<Request>(&mut bad.as_slice()),
            Err(FrameError::Garbled(_))
        ));
    }
}
