//! Presenting a run: a readable table, JSON, and CSV tables.

use std::fmt::Write as _;
use std::path::Path;

use crate::sim::RunResult;

/// The plateau table, per-law contributions and the energy balance, for people.
pub fn to_text(r: &RunResult) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "rig {}  drive {}  steps {}  max friction iterations {}",
        r.rig, r.drive, r.steps, r.max_friction_iterations
    );
    let _ = writeln!(
        out,
        "\n{:>10} {:>12} {:>14} {:>8}",
        "set rpm", "mean rpm", "torque N m", "oil C"
    );
    for p in &r.plateaus {
        let _ = writeln!(
            out,
            "{:>10.0} {:>12.2} {:>14.5} {:>8.1}",
            p.set_speed_rpm, p.mean_speed_rpm, p.motoring_torque_nm, p.oil_temp_c
        );
    }
    if r.plateaus.iter().any(|p| !p.joints.is_empty()) {
        let _ = writeln!(out, "\nper joint and law (friction torque at the crank, N m; power, W; regime shares b/m/h)");
        for p in &r.plateaus {
            let _ = writeln!(out, "  {:.0} rpm", p.set_speed_rpm);
            for j in &p.joints {
                let s = j.regime_share;
                let _ = writeln!(
                    out,
                    "    {:<10} {:<16} {:>10.5} {:>10.3}   {:.2}/{:.2}/{:.2}",
                    j.joint,
                    j.law,
                    j.friction_torque_nm,
                    j.power_w,
                    s.boundary,
                    s.mixed,
                    s.hydrodynamic
                );
            }
        }
    }
    let e = &r.energy;
    let _ = writeln!(
        out,
        "\nenergy: motor work {:.4} J = energy change {:.4} J + dissipated {:.4} J + residual {:.3e} J (relative {:.2e})",
        e.motor_work_j, e.mechanical_energy_change_j, e.dissipated_j, e.residual_j, e.relative_residual
    );
    if !r.law_time.is_empty() {
        let _ = writeln!(out, "\ntime in laws (sampled):");
        for l in &r.law_time {
            let per_call = if l.calls > 0 {
                l.seconds / l.calls as f64 * 1e9
            } else {
                0.0
            };
            let _ = writeln!(
                out,
                "  {:<10} {:<16} {:>10} calls {:>9.4} s ({:.0} ns per call)",
                l.joint, l.law, l.calls, l.seconds, per_call
            );
        }
    }
    for w in &r.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// `plateaus.csv` and `joints.csv` in `dir`.
pub fn write_csv(r: &RunResult, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut p = String::from("set_speed_rpm,mean_speed_rpm,motoring_torque_nm,oil_temp_c,viscosity_pa_s,window_start_s,window_end_s,revolutions\n");
    for x in &r.plateaus {
        let _ = writeln!(
            p,
            "{},{},{},{},{},{},{},{}",
            x.set_speed_rpm,
            x.mean_speed_rpm,
            x.motoring_torque_nm,
            x.oil_temp_c,
            x.viscosity_pa_s,
            x.window_s[0],
            x.window_s[1],
            x.revolutions
        );
    }
    crate::output::write_atomic(&dir.join("plateaus.csv"), p.as_bytes())?;
    let mut j = String::from("set_speed_rpm,joint,law,friction_torque_nm,power_w,mean_normal_load_n,share_none,share_boundary,share_mixed,share_hydrodynamic\n");
    for x in &r.plateaus {
        for l in &x.joints {
            let s = l.regime_share;
            let _ = writeln!(
                j,
                "{},{},{},{},{},{},{},{},{},{}",
                x.set_speed_rpm,
                l.joint,
                l.law,
                l.friction_torque_nm,
                l.power_w,
                l.mean_normal_load_n,
                s.none,
                s.boundary,
                s.mixed,
                s.hydrodynamic
            );
        }
    }
    crate::output::write_atomic(&dir.join("joints.csv"), j.as_bytes())
}

/// The side-by-side table, per-joint contributions and each law set's RMSE and largest error.
pub fn comparison_text(c: &crate::study::Comparison) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "rig {}  data {}  mode {}\n",
        c.rig, c.data_file, c.mode
    );
    let _ = write!(out, "{:>7} {:>9}", "rpm", "measured");
    for s in &c.sets {
        let w = s.lawset.len().max(9);
        let _ = write!(out, "  {:>w$} {:>7}", s.lawset, "error");
    }
    let _ = writeln!(out, "\n{:>7} {:>9}", "", "N m");
    for (i, d) in c.data.iter().enumerate() {
        let _ = write!(out, "{:>7.0} {:>9.3}", d.speed_rpm, d.torque_nm);
        for s in &c.sets {
            let w = s.lawset.len().max(9);
            let m = s
                .run
                .plateaus
                .get(i)
                .map_or(f64::NAN, |p| p.motoring_torque_nm);
            let _ = write!(
                out,
                "  {:>w$.3} {:>+7.3}",
                m,
                s.errors_nm.get(i).copied().unwrap_or(f64::NAN)
            );
        }
        out.push('\n');
    }
    let _ = write!(out, "{:>17}", "RMSE");
    for s in &c.sets {
        let w = s.lawset.len().max(9);
        let _ = write!(out, "  {:>w$.3} {:>7}", s.rmse_nm, "");
    }
    let _ = write!(out, "\n{:>17}", "max |error|");
    for s in &c.sets {
        let w = s.lawset.len().max(9);
        let _ = write!(out, "  {:>w$.3} {:>7}", s.max_abs_error_nm, "");
    }
    out.push_str("\n\nper-joint contributions (friction torque at the crank, N m)\n");
    for s in &c.sets {
        let _ = writeln!(out, "  {}", s.lawset);
        let Some(first) = s.run.plateaus.first() else {
            continue;
        };
        let labels: Vec<String> = first
            .joints
            .iter()
            .map(|j| format!("{}:{}", j.joint, j.law))
            .collect();
        let _ = write!(out, "  {:>7}", "rpm");
        for l in &labels {
            let _ = write!(out, " {:>24}", l);
        }
        out.push('\n');
        for p in &s.run.plateaus {
            let _ = write!(out, "  {:>7.0}", p.set_speed_rpm);
            for j in &p.joints {
                let _ = write!(out, " {:>24.4}", j.friction_torque_nm);
            }
            out.push('\n');
        }
        for w in &s.run.warnings {
            let _ = writeln!(out, "  warning: {w}");
        }
    }
    out
}

/// `comparison.csv`: one row per speed and law set.
pub fn comparison_csv(c: &crate::study::Comparison) -> String {
    let mut out = String::from(
        "speed_rpm,measured_torque_nm,oil_temp_c,lawset,model_torque_nm,error_nm,mean_speed_rpm\n",
    );
    for s in &c.sets {
        for (i, d) in c.data.iter().enumerate() {
            if let Some(p) = s.run.plateaus.get(i) {
                let _ = writeln!(
                    out,
                    "{},{},{},{},{},{},{}",
                    d.speed_rpm,
                    d.torque_nm,
                    d.oil_temp_c,
                    s.lawset,
                    p.motoring_torque_nm,
                    s.errors_nm[i],
                    p.mean_speed_rpm
                );
            }
        }
    }
    out
}

/// The calibration report: values, residual per speed, RMSE and warnings.
pub fn fit_text(r: &crate::fit::FitResult) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "law set {}: {} parameters, {} model evaluations, stopped: {}\n",
        r.lawset,
        r.params.len(),
        r.evaluations,
        r.termination
    );
    let _ = writeln!(
        out,
        "{:<36} {:>12} {:>12} {:>12}   bounds",
        "parameter", "start", "fitted", "1 sigma"
    );
    for i in 0..r.params.len() {
        let _ = writeln!(
            out,
            "{:<36} {:>12.5e} {:>12.5e} {:>12.2e}   [{}, {}]",
            r.params[i], r.start[i], r.values[i], r.std_dev[i], r.bounds[i][0], r.bounds[i][1]
        );
    }
    let _ = writeln!(
        out,
        "\n{:>7} {:>10} {:>10} {:>10}",
        "rpm", "measured", "model", "residual"
    );
    for i in 0..r.speeds_rpm.len() {
        let _ = writeln!(
            out,
            "{:>7.0} {:>10.3} {:>10.3} {:>+10.4}",
            r.speeds_rpm[i], r.measured_nm[i], r.model_nm[i], r.residuals_nm[i]
        );
    }
    let _ = writeln!(out, "\nRMSE {:.4} N m", r.rmse_nm);
    for w in &r.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// The mass-response tables. The FEDEM thesis's change (table 10.6 minus 10.5) is a column
/// only beside the thesis's own law set, labelled as the thesis's; other law sets have none.
pub fn mass_text(r: &[crate::study::MassResponse]) -> String {
    let mut out = String::new();
    for set in r {
        let thesis = set.changes.iter().any(|c| c.fedem_change_nm.is_some());
        let _ = writeln!(out, "law set {}: {:?} scaled", set.lawset, set.body);
        let _ = write!(
            out,
            "{:>7} {:>6} {:>10} {:>10} {:>10}",
            "rpm", "scale", "original", "scaled", "change"
        );
        if thesis {
            let _ = write!(out, " {:>26}", "FEDEM thesis (T 10.6-10.5)");
        }
        out.push('\n');
        for c in &set.changes {
            let _ = write!(
                out,
                "{:>7.0} {:>6.2} {:>10.4} {:>10.4} {:>+10.4}",
                c.speed_rpm, c.scale, c.original_nm, c.scaled_nm, c.change_nm
            );
            if thesis {
                let fedem = c
                    .fedem_change_nm
                    .map_or(String::new(), |f| format!("{f:+.3}"));
                let _ = write!(out, " {fedem:>26}");
            }
            out.push('\n');
            for j in &c.joints {
                let _ = writeln!(out, "        {:<10} {:<16} change {:>+9.5} N m   mean normal load change {:>+9.2} N", j.joint, j.law, j.change_nm, j.normal_load_change_n);
            }
        }
        out.push('\n');
    }
    out
}

/// The sweep's tables for people: the oil and its viscosity at each temperature, then per law
/// set the motoring torque with speeds as rows and temperatures as columns.
pub fn sweep_text(s: &crate::study::Sweep) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "rig {}  mode {}", s.rig, s.mode);
    let _ = writeln!(out, "oil: {}", s.oil.description);
    let _ = write!(out, "viscosity (mPa s):");
    for (t, v) in s.temps_c.iter().zip(&s.viscosities_pa_s) {
        let _ = write!(out, "  {t} C {:.2}", v * 1e3);
    }
    out.push('\n');
    let n = s.speeds_rpm.len();
    for set in &s.sets {
        let _ = writeln!(out, "\nlaw set {}: motoring torque, N m", set.lawset);
        let _ = write!(out, "{:>7}", "rpm");
        for t in &s.temps_c {
            let _ = write!(out, " {:>9}", format!("{t} C"));
        }
        out.push('\n');
        for (i, rpm) in s.speeds_rpm.iter().enumerate() {
            let _ = write!(out, "{rpm:>7.0}");
            for k in 0..s.temps_c.len() {
                let _ = write!(out, " {:>9.4}", set.torque(k, i, n));
            }
            out.push('\n');
        }
        for w in &set.warnings {
            let _ = writeln!(out, "warning: {w}");
        }
    }
    out
}

/// `sweep.csv`: one row per law set, temperature and speed (in the JSON's order: law set, then
/// temperature, then speed), with the friction torque of each joint (all its laws summed) in
/// its own column `<joint>_friction_nm`. Numbers are written in Rust's shortest round-trip form,
/// so they parse back to exactly the JSON's values.
pub fn sweep_csv(s: &crate::study::Sweep) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = [
        "lawset",
        "speed_rpm",
        "oil_temp_c",
        "viscosity_pa_s",
        "torque_nm",
    ]
    .iter()
    .map(|h| h.to_string())
    .collect();
    header.extend(
        crate::rig::JOINT_NAMES
            .iter()
            .map(|j| format!("{j}_friction_nm")),
    );
    w.write_record(&header)?;
    for set in &s.sets {
        for p in &set.points {
            let mut row = vec![
                set.lawset.clone(),
                p.speed_rpm.to_string(),
                p.oil_temp_c.to_string(),
                p.viscosity_pa_s.to_string(),
                p.torque_nm.to_string(),
            ];
            row.extend(p.joints.iter().map(|j| j.friction_torque_nm.to_string()));
            w.write_record(&row)?;
        }
    }
    let bytes = w
        .into_inner()
        .map_err(|e| csv::Error::from(e.into_error()))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}
