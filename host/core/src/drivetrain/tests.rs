//! The chain's modes and harmonic response against closed-form two- and three-inertia chains.

use super::*;
use std::f64::consts::TAU;

fn shaft(name: &str, k: f64, c: f64) -> ElementSpec {
    ElementSpec::Shaft {
        name: name.into(),
        stiffness_nm_per_rad: k,
        damping_nm_s_per_rad: c,
        backlash_rad: 0.0,
    }
}

fn transducer(k: f64, c: f64) -> ElementSpec {
    ElementSpec::Transducer {
        name: "t".into(),
        stiffness_nm_per_rad: k,
        damping_nm_s_per_rad: c,
        rated_torque_nm: 5.0,
        limit_torque_nm: 7.5,
        oscillation_width_nm: 4.0,
        cutoff_hz: 1000.0,
    }
}

fn daq() -> DaqSpec {
    DaqSpec {
        sample_rate_hz: 1200.0,
        lowpass_hz: 200.0,
        range_nm: 10.0,
        record_s: 1.0,
    }
}

fn spec(motor: f64, elements: Vec<ElementSpec>) -> DrivetrainSpec {
    DrivetrainSpec {
        motor: MotorSpec {
            inertia_kg_m2: motor,
        },
        elements,
        daq: daq(),
    }
}

const FREE: MotorHold = MotorHold::Pi { kp: 0.0, ki: 0.0 };

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

#[test]
fn two_inertias_free_free_and_clamped() {
    let (j1, j2, k) = (0.003, 0.0045, 290.0);
    let chain = spec(j1, vec![transducer(k, 0.0)]).chain(j2).unwrap();
    let modes = chain.modes(FREE);
    assert_eq!(modes.len(), 2);
    assert!(
        modes[0].frequency_hz.abs() < 1e-6,
        "rigid mode {}",
        modes[0].frequency_hz
    );
    let exact = (k * (1.0 / j1 + 1.0 / j2)).sqrt() / TAU;
    assert!(
        close(modes[1].frequency_hz, exact, 1e-9),
        "{} vs {exact}",
        modes[1].frequency_hz
    );
    // Node amplitudes of the elastic mode are in the inverse ratio of the inertias.
    let s = &modes[1].shape;
    assert!(close(-s[0] / s[1], j2 / j1, 1e-9));
    // Motor held by the prescribed drive: the crank alone on the spring.
    let held = chain.modes(MotorHold::Prescribed);
    assert_eq!(held.len(), 1);
    assert!(close(held[0].frequency_hz, (k / j2).sqrt() / TAU, 1e-9));
}

#[test]
fn three_inertias_free_free_match_the_characteristic_equation() {
    let (j1, j2, j3, k1, k2) = (0.0021, 1.5e-4, 0.0042, 410.0, 290.0);
    let chain = spec(
        j1,
        vec![
            shaft("belt-like", k1, 0.0),
            ElementSpec::Inertia {
                name: "axle".into(),
                inertia_kg_m2: j2,
            },
            transducer(k2, 0.0),
        ],
    )
    .chain(j3)
    .unwrap();
    // w^4 - b w^2 + c = 0 for the two elastic modes of a free-free three-inertia chain.
    let b = k1 * (1.0 / j1 + 1.0 / j2) + k2 * (1.0 / j2 + 1.0 / j3);
    let c = k1 * k2 * (j1 + j2 + j3) / (j1 * j2 * j3);
    let disc = (b * b - 4.0 * c).sqrt();
    let lo = ((b - disc) / 2.0).sqrt() / TAU;
    let hi = ((b + disc) / 2.0).sqrt() / TAU;
    let modes = chain.modes(FREE);
    assert!(modes[0].frequency_hz.abs() < 1e-6);
    assert!(
        close(modes[1].frequency_hz, lo, 1e-9),
        "{} vs {lo}",
        modes[1].frequency_hz
    );
    assert!(
        close(modes[2].frequency_hz, hi, 1e-9),
        "{} vs {hi}",
        modes[2].frequency_hz
    );
    for m in &modes[1..] {
        let share: f64 = m.strain_energy_share.iter().sum();
        assert!(close(share, 1.0, 1e-12));
    }
}

#[test]
fn a_belt_reflects_the_motor_by_its_ratio_squared() {
    // Motor at half the crank's speed (driven pulley twice as fast): J_m / 4 at the crank.
    let (jm, jc, k) = (0.004, 0.0042, 400.0);
    let chain = spec(
        jm,
        vec![ElementSpec::Belt {
            name: "belt".into(),
            ratio: 2.0,
            stiffness_nm_per_rad: k,
            damping_nm_s_per_rad: 0.0,
        }],
    );
    let err = chain.chain(jc).unwrap_err();
    assert!(err.to_string().contains("no transducer"), "{err}");
    let chain = spec(
        jm,
        vec![
            ElementSpec::Belt {
                name: "belt".into(),
                ratio: 2.0,
                stiffness_nm_per_rad: k,
                damping_nm_s_per_rad: 0.0,
            },
            ElementSpec::Inertia {
                name: "hub".into(),
                inertia_kg_m2: 1e-12,
            },
            transducer(1e12, 0.0),
        ],
    )
    .chain(jc)
    .unwrap();
    assert!(close(chain.inertias[0], jm / 4.0, 1e-15));
    assert!(close(chain.ratios[0], 0.5, 1e-15));
    let exact = (k * (4.0 / jm + 1.0 / (jc + 1e-12))).sqrt() / TAU;
    let modes = chain.modes(FREE);
    assert!(
        close(modes[1].frequency_hz, exact, 1e-6),
        "{} vs {exact}",
        modes[1].frequency_hz
    );
}

#[test]
fn harmonic_response_of_one_clamped_inertia_is_the_receptance() {
    let (jm, jc, k, c) = (0.01, 0.0042, 290.0, 0.05);
    let chain = spec(jm, vec![transducer(k, c)]).chain(jc).unwrap();
    for omega in [0.0, 100.0, 262.8, 1000.0] {
        let f = Complex::new(2.0, -1.0);
        let x = chain.harmonic(MotorHold::Prescribed, f, omega).unwrap();
        let exact = f / Complex::new(k - omega * omega * jc, omega * c);
        assert_eq!(x[0], Complex::new(0.0, 0.0));
        assert!(
            (x[1] - exact).norm() <= 1e-12 * exact.norm(),
            "{omega}: {} vs {exact}",
            x[1]
        );
    }
}

#[test]
fn bad_chains_are_refused_naming_the_element() {
    let two = spec(0.01, vec![transducer(290.0, 0.0), shaft("s", 1.0, 0.0)]);
    let e = two.chain(0.004).unwrap_err();
    assert_eq!(e.field, "elements[1]");
    let neg = spec(0.01, vec![shaft("s", -1.0, 0.0)]);
    let e = neg.chain(0.004).unwrap_err();
    assert_eq!(e.field, "elements[0].stiffness_nm_per_rad");
    let ends = spec(
        0.01,
        vec![
            transducer(290.0, 0.0),
            ElementSpec::Inertia {
                name: "a".into(),
                inertia_kg_m2: 1e-4,
            },
        ],
    );
    assert_eq!(ends.chain(0.004).unwrap_err().field, "elements");
}

#[test]
fn backlash_leaves_a_dead_band() {
    let mut s = spec(0.01, vec![transducer(100.0, 0.0)]);
    s.elements[0] = ElementSpec::Shaft {
        name: "loose".into(),
        stiffness_nm_per_rad: 100.0,
        damping_nm_s_per_rad: 0.0,
        backlash_rad: 0.02,
    };
    s.elements.push(ElementSpec::Inertia {
        name: "m".into(),
        inertia_kg_m2: 1e-3,
    });
    s.elements.push(transducer(290.0, 0.0));
    let chain = s.chain(0.004).unwrap();
    let w = [0.0; 3];
    assert_eq!(chain.spring_torque(0, &[0.009, 0.0, 0.0], &w), 0.0);
    assert!(close(
        chain.spring_torque(0, &[0.03, 0.0, 0.0], &w),
        100.0 * 0.02,
        1e-12
    ));
    assert!(close(
        chain.spring_torque(0, &[-0.03, 0.0, 0.0], &w),
        -100.0 * 0.02,
        1e-12
    ));
}

/// A one-throw elastic crankshaft held at its flywheel: throw `J1` on the rear section `k1`,
/// the pulley `J2` on the front section `k0`. Its two modes solve
/// `J1 J2 w^4 - (J1 k0 + J2 (k0 + k1)) w^2 + k0 k1 = 0`.
#[test]
fn a_one_throw_crankshaft_held_at_its_flywheel_has_the_two_mass_modes() {
    let (j1, j2, k0, k1) = (0.007, 0.004, 6.0e5, 3.3e5);
    let section = |k: f64| SectionSpec {
        stiffness_nm_per_rad: k,
        damping_nm_s_per_rad: 0.0,
    };
    let spec = CrankshaftSpec {
        flywheel_inertia_kg_m2: 0.1,
        pulley_inertia_kg_m2: j2,
        sections: vec![section(k0), section(k1)],
        damper: None,
    };
    let chain = Chain::crankshaft(spec.crank_end(&[j1]).unwrap(), 0.0).unwrap();
    assert_eq!(chain.names, ["flywheel", "throw 1", "front pulley"]);
    assert_eq!(chain.throws, [1]);
    assert!(chain.instrument.is_none());
    let (a, b, c) = (j1 * j2, -(j1 * k0 + j2 * (k0 + k1)), k0 * k1);
    let root = (b * b - 4.0 * a * c).sqrt();
    let expected = [(-b - root) / (2.0 * a), (-b + root) / (2.0 * a)].map(|w2| w2.sqrt() / TAU);
    let modes = chain.modes(MotorHold::Prescribed);
    assert_eq!(modes.len(), 2);
    for (m, f) in modes.iter().zip(expected) {
        assert!(
            close(m.frequency_hz, f, 1e-9),
            "{} Hz against {f} Hz",
            m.frequency_hz
        );
    }
    // A wrong count of sections names the field and the count expected.
    let short = CrankshaftSpec {
        sections: vec![section(k0)],
        ..spec
    };
    let e = short.crank_end(&[j1]).map(|_| ()).unwrap_err();
    assert_eq!(e.field, "sections");
    assert!(e.message.contains("expected 2 sections"), "{}", e.message);
}
