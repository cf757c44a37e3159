//! `tribo run --timeseries`: the per-step CSV, written by an observer of the run so the solver
//! core does no I/O. One line per accepted step: time, crank angle, speed, motoring torque
//! (raw and low-pass filtered) and every joint's normal load.

use std::io::Write;

use tribo_core::cycle::rad_s_to_rpm;
use tribo_core::observe::{ObserverError, StepObserver, StepSample};

/// Why the time series could not be written.
#[derive(Debug, thiserror::Error)]
#[error("writing the time series: {0}")]
pub struct TimeSeriesError(#[from] std::io::Error);

/// Writes the time series as CSV to any writer (a buffered, atomically renamed file in the CLI).
pub struct TimeSeries<W: Write> {
    out: W,
}

impl<W: Write> TimeSeries<W> {
    /// A time series written to `out`.
    pub fn new(out: W) -> Self {
        Self { out }
    }

    /// The writer back, to commit or flush it.
    pub fn into_inner(self) -> W {
        self.out
    }

    fn header(&mut self, joints: &[&str]) -> std::io::Result<()> {
        write!(
            self.out,
            "time_s,theta_rad,speed_rpm,motoring_torque_nm,motoring_torque_filtered_nm"
        )?;
        for name in joints {
            write!(self.out, ",{name}_normal_load_n")?;
        }
        writeln!(self.out)
    }

    fn line(&mut self, s: &StepSample<'_>) -> std::io::Result<()> {
        write!(
            self.out,
            "{:.7},{:.6},{:.4},{:.6},{:.6}",
            s.time_s,
            s.crank_angle_rad,
            rad_s_to_rpm(s.speed_rad_s),
            s.motoring_torque_nm,
            s.filtered_torque_nm
        )?;
        for nl in s.normal_loads_n {
            write!(self.out, ",{nl:.4}")?;
        }
        writeln!(self.out)
    }
}

impl<W: Write> StepObserver for TimeSeries<W> {
    fn start(&mut self, joints: &[&str]) -> Result<(), ObserverError> {
        self.header(joints)
            .map_err(|e| Box::new(TimeSeriesError(e)) as ObserverError)
    }

    fn step(&mut self, sample: &StepSample<'_>) -> Result<(), ObserverError> {
        self.line(sample)
            .map_err(|e| Box::new(TimeSeriesError(e)) as ObserverError)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_header_and_lines_in_the_documented_format() {
        let mut ts = TimeSeries::new(Vec::new());
        ts.start(&["a", "b", "c", "d", "e"]).expect("header");
        let loads = [1.0, 2.0, 3.5, 4.25, 0.0];
        let sample = StepSample {
            time_s: 0.5,
            crank_angle_rad: 1.0,
            speed_rad_s: std::f64::consts::PI,
            motoring_torque_nm: -0.25,
            filtered_torque_nm: 0.125,
            normal_loads_n: &loads,
        };
        ts.step(&sample).expect("line");
        let text = String::from_utf8(ts.into_inner()).expect("utf-8");
        let mut lines = text.lines();
        assert_eq!(
            lines.next(),
            Some("time_s,theta_rad,speed_rpm,motoring_torque_nm,motoring_torque_filtered_nm,a_normal_load_n,b_normal_load_n,c_normal_load_n,d_normal_load_n,e_normal_load_n")
        );
        assert_eq!(
            lines.next(),
            Some(
                "0.5000000,1.000000,30.0000,-0.250000,0.125000,1.0000,2.0000,3.5000,4.2500,0.0000"
            )
        );
    }

    /// A writer that fails: the run must stop with the error.
    struct Broken;
    impl Write for Broken {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk full"))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_failing_writer_is_an_error() {
        let mut ts = TimeSeries::new(Broken);
        let e = ts.start(&["a"]).expect_err("fails");
        assert!(e.to_string().contains("disk full"), "{e}");
    }
}
