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
