//! Oil temperature responses of the bundled law sets (issue 26, points 3 and 6;
//! docs/temperature.md): the physics each set's laws encode, asserted on `tribo sweep`'s
//! steady results. Expected values come from lubrication theory (full-film friction of a
//! slider scales as the root of viscosity, a journal's at most as viscosity itself, rolling
//! bearings' catalogue moments not at all), never from a previous run.

mod common;

use common::*;

/// `tribo sweep RIG --lawset SET` at these temperatures and speeds: per point (speed, temperature,
/// viscosity, motoring torque, the friction torque of every joint whose name starts `prefix`).
fn sweep(
    rig: &str,
    set: &str,
    temps: &str,
    speeds: &str,
    prefix: &str,
) -> Vec<(f64, f64, f64, f64, f64)> {
    let dir = tempfile::tempdir().expect("temp dir");
    let j = json_in(
        &[
            "sweep", rig, "--lawset", set, "--temps", temps, "--speeds", speeds, "--out", "sw",
            "--json", "--quiet",
        ],
        dir.path(),
    );
    assert!(
        j["failed"].as_array().is_none_or(|f| f.is_empty()),
        "{rig} / {set}: {}",
        j["failed"]
    );
    j["sets"][0]["points"]
        .as_array()
        .expect("points")
        .iter()
        .map(|p| {
            let joints: f64 = p["joints"]
                .as_array()
                .expect("joints")
                .iter()
                .filter(|x| x["joint"].as_str().unwrap_or("").starts_with(prefix))
                .map(|x| x["friction_torque_nm"].as_f64().unwrap_or(f64::NAN))
                .sum();
            (
                p["speed_rpm"].as_f64().unwrap_or(f64::NAN),
                p["oil_temp_c"].as_f64().unwrap_or(f64::NAN),
                p["viscosity_pa_s"].as_f64().unwrap_or(f64::NAN),
                p["torque_nm"].as_f64().unwrap_or(f64::NAN),
                joints,
            )
        })
        .collect()
}

/// The point at this speed and temperature.
fn at(points: &[(f64, f64, f64, f64, f64)], rpm: f64, t: f64) -> (f64, f64, f64) {
    let p = points
        .iter()
        .find(|p| p.0 == rpm && p.1 == t)
        .unwrap_or_else(|| panic!("no point at {rpm} rpm, {t} C"));
    (p.2, p.3, p.4)
}

/// `stribeck-duty`, made consistent, on the CRF 250 R at 3000 and 6000 rpm: its piston runs in
/// full film over nearly all of each revolution, where the duty-parameter law is the slider's
/// `c sqrt(eta U W L)`, so from 70 to 90 C the piston's friction falls as `sqrt(eta)`
/// (`d ln T / d ln eta = +0.5`, within 2%), and the whole set's torque falls with it, diluted
/// by the viscosity-blind SKF bearing moments: a response between 0 and 0.5, the sign and size
/// of the thesis's two runs (about +0.5).
#[test]
fn stribeck_duty_torque_falls_with_temperature_as_the_root_of_viscosity() {
    let points = sweep(
        "crf250r-motored",
        "stribeck-duty",
        "70,90",
        "3000,6000",
        "piston",
    );
    for rpm in [3000.0, 6000.0] {
        let (eta70, t70, p70) = at(&points, rpm, 70.0);
        let (eta90, t90, p90) = at(&points, rpm, 90.0);
        let dln_eta = (eta90 / eta70).ln();
        let piston = (p90 / p70).ln() / dln_eta;
        assert!(
            (piston - 0.5).abs() < 0.01,
            "{rpm} rpm: piston d ln T / d ln eta {piston}, the slider's 0.5"
        );
        let total = (t90 / t70).ln() / dln_eta;
        assert!(
            total > 0.2 && total <= 0.5 + 1e-9,
            "{rpm} rpm: d ln T / d ln eta {total}"
        );
        assert!(t90 < t70, "{rpm} rpm: torque rose {t70} -> {t90}");
    }
}

/// Where full-film friction dominates, the physical sets lose torque as the oil warms, at every
/// speed and every step of 40-110 C: `mixed-film`'s piston on the CRF (slider films,
/// `sqrt(eta)`, less where asperities touch), `4b11-physical`'s main bearings on the
/// inline-4 (plain journals: between the loaded journal's eccentricity term, which falls
/// slowly with viscosity, and Petroff's `eta`, so their response lies in (0, 1]), and
/// `crf250r-physical`'s piston on the CRF (rings near the slider's 0.5, the skirt's nearly
/// concentric film near Petroff's 1: between 0 and 1), with the whole set's torque falling
/// (its roller bearings and churning are viscosity-blind at these temperatures).
#[test]
fn physical_sets_lose_torque_as_the_oil_warms() {
    let temps = [40.0, 70.0, 90.0, 110.0];
    for (rig, set, speeds, prefix) in [
        ("crf250r-motored", "mixed-film", "3000,9000", "piston"),
        ("inline4-4b11", "4b11-physical", "1000,6000", "main_"),
        ("crf250r-motored", "crf250r-physical", "3000,9000", "piston"),
    ] {
        let points = sweep(rig, set, "40,70,90,110", speeds, prefix);
        for rpm in speeds.split(',').map(|s| s.parse::<f64>().expect("speed")) {
            for w in temps.windows(2) {
                let (eta_a, t_a, j_a) = at(&points, rpm, w[0]);
                let (eta_b, t_b, j_b) = at(&points, rpm, w[1]);
                assert!(eta_b < eta_a);
                // The full-film joints lose torque; on the CRF they are the whole set's
                // viscous part (the SKF bearings are viscosity-blind), so the total falls too.
                assert!(
                    j_b < j_a,
                    "{rig} / {set} at {rpm} rpm: {prefix}* {j_a} at {} C -> {j_b} at {} C",
                    w[0],
                    w[1]
                );
                if set != "4b11-physical" {
                    assert!(t_b < t_a, "{set} at {rpm} rpm: torque {t_a} -> {t_b}");
                }
                let response = (j_b / j_a).ln() / (eta_b / eta_a).ln();
                // The slider's 0.5, less where asperities touch; the friction's own feedback
                // into the joint reactions moves it by a few 1e-4.
                let (lo, hi) = if set == "mixed-film" {
                    (0.45, 0.5 + 1e-3)
                } else {
                    (0.0, 1.0 + 1e-6)
                };
                assert!(
                    response > lo && response <= hi,
                    "{rig} / {set} at {rpm} rpm, {}-{} C: {prefix}* d ln T / d ln eta {response}",
                    w[0],
                    w[1]
                );
            }
        }
    }
}
