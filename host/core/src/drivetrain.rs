//! The rig's drivetrain: the torsional chain from the drive motor to the crank (rotor, belt,
//! shafts, couplings, one torque transducer) as rig-file data ([`DrivetrainSpec`]) and as a
//! lumped model reflected to crank speed ([`Chain`]): its undamped modes, its linear harmonic
//! response and the forces its elements exert at any state. The solver integrates the chain's
//! degrees of freedom with the crank train (`sim::torsional`); `tribo modes` prints the modes.
//!
//! Conventions: node 0 is the motor, the last node the crank; each node has a speed ratio
//! `r` (its speed over the crank's). An inertia `J` at a node is `J r^2` at crank speed, a
//! stiffness `k` between nodes (given at the element's crank-side end) `k r^2`, a torque `T`
//! there `T r`: the chain reflected to crank speed has the same kinetic and strain energy and
//! the same power as the real one.

use nalgebra::{Complex, DMatrix, DVector, SymmetricEigen};
use tribo_plugin_api::serde::{Deserialize, Serialize};

/// The drivetrain of a rig file (`[drivetrain]`): the motor, the elements from the motor to
/// the crank in order, and the data acquisition behind the transducer.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct DrivetrainSpec {
    /// The drive motor (its rotor and what turns rigidly with it).
    pub motor: MotorSpec,
    /// The chain from the motor to the crank, in order: compliant elements (`shaft`, `belt`,
    /// `transducer`) separated by `inertia` elements; the first and last are compliant.
    pub elements: Vec<ElementSpec>,
    /// The data acquisition that records the transducer's signal.
    pub daq: DaqSpec,
}

/// The drive motor.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct MotorSpec {
    /// Rotor inertia with its pulley, kg m^2 (at motor speed).
    pub inertia_kg_m2: f64,
}

/// One element of the chain.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ElementSpec {
    /// A rotating mass between two compliant elements (an axle, a pulley, a hub).
    Inertia {
        /// Its name in the results.
        name: String,
        /// kg m^2, at its own speed.
        inertia_kg_m2: f64,
    },
    /// A shaft or coupling: torsional stiffness and viscous damping, optionally with play.
    Shaft {
        /// Its name in the results.
        name: String,
        /// N m/rad.
        stiffness_nm_per_rad: f64,
        /// N m s/rad.
        #[serde(default)]
        damping_nm_s_per_rad: f64,
        /// Total angular play, rad (free travel before the spring engages); none by default.
        #[serde(default)]
        backlash_rad: f64,
    },
    /// A belt: a speed ratio and the spans' stiffness and damping.
    Belt {
        /// Its name in the results.
        name: String,
        /// Driven (crank-side) pulley speed over driving pulley speed.
        ratio: f64,
        /// Torsional stiffness of the spans at the driven pulley, N m/rad.
        stiffness_nm_per_rad: f64,
        /// Damping at the driven pulley, N m s/rad.
        #[serde(default)]
        damping_nm_s_per_rad: f64,
    },
    /// The torque transducer: its measuring shaft's stiffness and damping and its rating. Its
    /// shaft torque is the measured torque.
    Transducer {
        /// Its name in the results.
        name: String,
        /// Measuring-shaft stiffness, N m/rad.
        stiffness_nm_per_rad: f64,
        /// N m s/rad.
        #[serde(default)]
        damping_nm_s_per_rad: f64,
        /// Nominal (rated) torque, N m.
        rated_torque_nm: f64,
        /// Limit torque (static), N m.
        limit_torque_nm: f64,
        /// Permitted oscillation width (peak to peak), N m.
        oscillation_width_nm: f64,
        /// Cut-off of the transducer's own signal electronics (first order), Hz.
        cutoff_hz: f64,
    },
}

/// The data acquisition: sampling, low-pass and input range.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct DaqSpec {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Cut-off of the amplifier's low-pass (first order), Hz.
    pub lowpass_hz: f64,
    /// The input range as torque, N m: samples beyond +-range are clipped.
    pub range_nm: f64,
    /// Length of the averaged record, s (the thesis's mean values: 1 s and 5 s).
    pub record_s: f64,
}

/// An engine's elastic crankshaft (`[engine.crankshaft]`): the throws turn as inertias of
/// their own, joined by the torsional stiffness of the journals and webs between them, with
/// the flywheel beyond the last main (where the drive or the drivetrain attaches) and the
/// front pulley beyond the first, optionally carrying a torsional damper.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct CrankshaftSpec {
    /// Flywheel (or drive flange) inertia, kg m^2.
    pub flywheel_inertia_kg_m2: f64,
    /// Front pulley (with its hub and the timing sprocket) inertia, kg m^2.
    pub pulley_inertia_kg_m2: f64,
    /// The shaft's sections from the front: pulley to the first throw, throw to throw in
    /// axial order, the last throw to the flywheel (throws + 1 sections).
    pub sections: Vec<SectionSpec>,
    /// A torsional damper on the front pulley: a ring on a rubber or viscous layer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damper: Option<DamperSpec>,
}

/// One section of the crankshaft between two of its masses.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    /// Torsional stiffness, N m/rad.
    pub stiffness_nm_per_rad: f64,
    /// Structural damping as a viscous equivalent, N m s/rad.
    #[serde(default)]
    pub damping_nm_s_per_rad: f64,
}

/// A torsional damper: its ring's inertia and the layer joining it to the pulley.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct DamperSpec {
    /// Ring inertia, kg m^2.
    pub inertia_kg_m2: f64,
    /// The layer's torsional stiffness, N m/rad.
    pub stiffness_nm_per_rad: f64,
    /// The layer's damping, N m s/rad.
    pub damping_nm_s_per_rad: f64,
}

/// The crank end of a chain: the rigid crank's one node, or an elastic crankshaft's nodes
/// (flywheel first) with the sections between them.
pub struct CrankEnd {
    names: Vec<String>,
    inertias: Vec<f64>,
    raws: Vec<Raw>,
    /// Each throw's node within these nodes (throws in axial order).
    throws: Vec<usize>,
}

impl CrankEnd {
    /// A rigid crank of cycle-mean inertia `inertia_kg_m2`.
    pub fn rigid(inertia_kg_m2: f64) -> Self {
        CrankEnd {
            names: vec!["crank".into()],
            inertias: vec![inertia_kg_m2],
            raws: Vec::new(),
            throws: vec![0],
        }
    }
}

impl CrankshaftSpec {
    /// The crankshaft's nodes from the flywheel to the pulley (and the damper's ring), with
    /// the throws' cycle-mean inertias `throw_inertias` (kg m^2, throws in axial order).
    pub fn crank_end(&self, throw_inertias: &[f64]) -> Result<CrankEnd, DrivetrainError> {
        let n = throw_inertias.len();
        positive("flywheel_inertia_kg_m2".into(), self.flywheel_inertia_kg_m2)?;
        positive("pulley_inertia_kg_m2".into(), self.pulley_inertia_kg_m2)?;
        if self.sections.len() != n + 1 {
            return Err(err(
                "sections",
                format!("expected {} sections (pulley to throw 1, one between each pair of the {n} throws, the last throw to the flywheel), got {}", n + 1, self.sections.len()),
            ));
        }
        let section = |i: usize, name: String| -> Result<Raw, DrivetrainError> {
            let s = &self.sections[i];
            positive(
                format!("sections[{i}].stiffness_nm_per_rad"),
                s.stiffness_nm_per_rad,
            )?;
            non_negative(
                format!("sections[{i}].damping_nm_s_per_rad"),
                s.damping_nm_s_per_rad,
            )?;
            Ok(Raw {
                name,
                k: s.stiffness_nm_per_rad,
                c: s.damping_nm_s_per_rad,
                backlash: 0.0,
                ratio: 1.0,
                rating: None,
            })
        };
        let throw = |j: usize| format!("throw {}", j + 1);
        let mut end = CrankEnd {
            names: vec!["flywheel".into()],
            inertias: vec![self.flywheel_inertia_kg_m2],
            raws: Vec::new(),
            throws: vec![0; n],
        };
        // From the flywheel towards the front: the throws in reverse axial order.
        for j in (0..n).rev() {
            let behind = if j + 1 == n {
                "flywheel".into()
            } else {
                throw(j + 1)
            };
            end.raws.push(section(
                j + 1,
                format!("crankshaft {}-{}", throw(j), behind),
            )?);
            end.throws[j] = end.names.len();
            end.names.push(throw(j));
            positive(format!("throw {} inertia", j + 1), throw_inertias[j])?;
            end.inertias.push(throw_inertias[j]);
        }
        end.raws
            .push(section(0, format!("crankshaft front pulley-{}", throw(0)))?);
        end.names.push("front pulley".into());
        end.inertias.push(self.pulley_inertia_kg_m2);
        if let Some(d) = &self.damper {
            positive("damper.inertia_kg_m2".into(), d.inertia_kg_m2)?;
            positive("damper.stiffness_nm_per_rad".into(), d.stiffness_nm_per_rad)?;
            non_negative("damper.damping_nm_s_per_rad".into(), d.damping_nm_s_per_rad)?;
            end.raws.push(Raw {
                name: "damper layer".into(),
                k: d.stiffness_nm_per_rad,
                c: d.damping_nm_s_per_rad,
                backlash: 0.0,
                ratio: 1.0,
                rating: None,
            });
            end.names.push("damper ring".into());
            end.inertias.push(d.inertia_kg_m2);
        }
        Ok(end)
    }
}

/// A drivetrain that cannot be built.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("drivetrain.{field}: {message}")]
pub struct DrivetrainError {
    /// The dotted field in `[drivetrain]` (`elements[2].stiffness_nm_per_rad`).
    pub field: String,
    /// What is wrong and what was expected.
    pub message: String,
}

fn err(field: impl Into<String>, message: impl Into<String>) -> DrivetrainError {
    DrivetrainError {
        field: field.into(),
        message: message.into(),
    }
}

/// One spring-damper of the reflected chain, between nodes `i` and `i + 1`.
#[derive(Debug, Clone, PartialEq)]
pub struct Spring {
    /// The element's name.
    pub name: String,
    /// Stiffness at crank speed, N m/rad.
    pub k: f64,
    /// Damping at crank speed, N m s/rad.
    pub c: f64,
    /// Play at crank speed, rad (total).
    pub backlash: f64,
    /// Torque at crank speed over the torque in the element itself (the element's `r`).
    pub ratio: f64,
}

/// The transducer's rating and signal path.
#[derive(Debug, Clone, PartialEq)]
pub struct Rating {
    /// The transducer's name.
    pub name: String,
    /// Which spring it is.
    pub spring: usize,
    /// N m.
    pub rated_nm: f64,
    /// N m.
    pub limit_nm: f64,
    /// Permitted peak-to-peak, N m.
    pub width_nm: f64,
    /// Transducer electronics cut-off, Hz.
    pub cutoff_hz: f64,
}

/// The chain reflected to crank speed: node inertias (motor first, crank last) and the springs
/// between neighbours.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    /// Node names, motor first, crank last.
    pub names: Vec<String>,
    /// Node inertias at crank speed, kg m^2 (the crank's: its cycle-mean inertia).
    pub inertias: Vec<f64>,
    /// Node speed over crank speed.
    pub ratios: Vec<f64>,
    /// `springs[i]` joins nodes `i` and `i + 1`.
    pub springs: Vec<Spring>,
    /// The measuring element and its acquisition (none on an engine's own crankshaft without
    /// a drivetrain).
    pub instrument: Option<(Rating, DaqSpec)>,
    /// Each crank throw's node (one node, the last, for a rigid crank): where the crank
    /// train's torques act.
    pub throws: Vec<usize>,
}

/// How the motor node is held in a linearised analysis: by the prescribed drive (its speed
/// imposed: a fixed node in the modes), or by the PI drive's controller (a spring `ki` and a
/// damper `kp` to the reference, at motor speed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotorHold {
    /// The motor follows the reference exactly.
    Prescribed,
    /// PI gains (N m per rad/s, N m per rad, at the motor).
    Pi {
        /// Proportional gain.
        kp: f64,
        /// Integral gain.
        ki: f64,
    },
}

fn positive(field: String, v: f64) -> Result<(), DrivetrainError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("expected a finite value > 0, got {v}")))
    }
}

fn non_negative(field: String, v: f64) -> Result<(), DrivetrainError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("expected a finite value >= 0, got {v}")))
    }
}

impl DaqSpec {
    fn check(&self) -> Result<(), DrivetrainError> {
        positive("daq.sample_rate_hz".into(), self.sample_rate_hz)?;
        positive("daq.lowpass_hz".into(), self.lowpass_hz)?;
        positive("daq.range_nm".into(), self.range_nm)?;
        positive("daq.record_s".into(), self.record_s)?;
        if self.record_s * self.sample_rate_hz > 1e7 {
            return Err(err(
                "daq.record_s",
                "the record holds over 1e7 samples; give a shorter record or a lower rate",
            ));
        }
        Ok(())
    }
}

/// A compliant element as the chain holds it, before reflection.
struct Raw {
    name: String,
    k: f64,
    c: f64,
    backlash: f64,
    ratio: f64,
    rating: Option<Rating>,
}

impl ElementSpec {
    /// The element's compliant part (none for an inertia), its fields checked.
    fn compliant(&self, at: &str) -> Result<Option<Raw>, DrivetrainError> {
        let f = |name: &str| format!("{at}.{name}");
        Ok(match self {
            ElementSpec::Inertia { inertia_kg_m2, .. } => {
                positive(f("inertia_kg_m2"), *inertia_kg_m2)?;
                None
            }
            ElementSpec::Shaft {
                name,
                stiffness_nm_per_rad: k,
                damping_nm_s_per_rad: c,
                backlash_rad,
            } => {
                positive(f("stiffness_nm_per_rad"), *k)?;
                non_negative(f("damping_nm_s_per_rad"), *c)?;
                non_negative(f("backlash_rad"), *backlash_rad)?;
                Some(Raw {
                    name: name.clone(),
                    k: *k,
                    c: *c,
                    backlash: *backlash_rad,
                    ratio: 1.0,
                    rating: None,
                })
            }
            ElementSpec::Belt {
                name,
                ratio,
                stiffness_nm_per_rad: k,
                damping_nm_s_per_rad: c,
            } => {
                positive(f("ratio"), *ratio)?;
                positive(f("stiffness_nm_per_rad"), *k)?;
                non_negative(f("damping_nm_s_per_rad"), *c)?;
                Some(Raw {
                    name: name.clone(),
                    k: *k,
                    c: *c,
                    backlash: 0.0,
                    ratio: *ratio,
                    rating: None,
                })
            }
            ElementSpec::Transducer { .. } => Some(self.transducer(at)?),
        })
    }

    fn transducer(&self, at: &str) -> Result<Raw, DrivetrainError> {
        let ElementSpec::Transducer {
            name,
            stiffness_nm_per_rad: k,
            damping_nm_s_per_rad: c,
            rated_torque_nm,
            limit_torque_nm,
            oscillation_width_nm,
            cutoff_hz,
        } = self
        else {
            return Err(err(at, "not a transducer"));
        };
        let f = |n: &str| format!("{at}.{n}");
        positive(f("stiffness_nm_per_rad"), *k)?;
        non_negative(f("damping_nm_s_per_rad"), *c)?;
        positive(f("rated_torque_nm"), *rated_torque_nm)?;
        positive(f("oscillation_width_nm"), *oscillation_width_nm)?;
        positive(f("cutoff_hz"), *cutoff_hz)?;
        if !(limit_torque_nm.is_finite() && *limit_torque_nm >= *rated_torque_nm) {
            return Err(err(
                f("limit_torque_nm"),
                format!("expected at least the rated torque {rated_torque_nm} N m, got {limit_torque_nm}"),
            ));
        }
        Ok(Raw {
            name: name.clone(),
            k: *k,
            c: *c,
            backlash: 0.0,
            ratio: 1.0,
            rating: Some(Rating {
                name: name.clone(),
                spring: 0,
                rated_nm: *rated_torque_nm,
                limit_nm: *limit_torque_nm,
                width_nm: *oscillation_width_nm,
                cutoff_hz: *cutoff_hz,
            }),
        })
    }
}

impl DrivetrainSpec {
    /// The chain reflected to crank speed, with the crank's cycle-mean inertia
    /// `crank_inertia_kg_m2` as its last node. Refuses a chain that does not alternate
    /// compliant elements and inertias, or that has not exactly one transducer.
    pub fn chain(&self, crank_inertia_kg_m2: f64) -> Result<Chain, DrivetrainError> {
        positive("crank inertia".into(), crank_inertia_kg_m2)?;
        self.chain_to(CrankEnd::rigid(crank_inertia_kg_m2))
    }

    /// The chain reflected to crank speed, ending in `end` (the rigid crank, or an elastic
    /// crankshaft from its flywheel).
    pub fn chain_to(&self, end: CrankEnd) -> Result<Chain, DrivetrainError> {
        positive("motor.inertia_kg_m2".into(), self.motor.inertia_kg_m2)?;
        self.daq.check()?;
        let (mut names, mut inertias) = (vec!["motor".to_string()], vec![self.motor.inertia_kg_m2]);
        let mut raws: Vec<Raw> = Vec::new();
        let mut expect_compliant = true;
        for (i, e) in self.elements.iter().enumerate() {
            let at = format!("elements[{i}]");
            match (e.compliant(&at)?, e) {
                (Some(raw), _) if expect_compliant => {
                    raws.push(raw);
                    expect_compliant = false;
                }
                (
                    None,
                    ElementSpec::Inertia {
                        name,
                        inertia_kg_m2,
                    },
                ) if !expect_compliant => {
                    names.push(name.clone());
                    inertias.push(*inertia_kg_m2);
                    expect_compliant = true;
                }
                (Some(_), _) => {
                    return Err(err(at, "two compliant elements in a row: put an `inertia` element (the mass between them) in between"));
                }
                (None, _) => {
                    return Err(err(at, "an inertia where a compliant element (shaft, belt or transducer) was expected: join neighbouring masses into one inertia"));
                }
            }
        }
        if raws.is_empty() || expect_compliant {
            return Err(err(
                "elements",
                "the chain must run motor, compliant element, [inertia, compliant element ...], crank: it must start and end with a shaft, belt or transducer",
            ));
        }
        let throws = end.throws.iter().map(|j| j + names.len()).collect();
        names.extend(end.names);
        inertias.extend(end.inertias);
        raws.extend(end.raws);
        let chain = reflect(names, inertias, raws, Some(self.daq.clone()), throws)?;
        if chain.instrument.is_none() {
            return Err(err(
                "elements",
                "no transducer: the chain needs one `transducer` element, whose torque is the measured torque",
            ));
        }
        Ok(chain)
    }
}

impl Chain {
    /// An engine's elastic crankshaft alone, the drive on its flywheel (whose node is then the
    /// motor's, its inertia with the drive's `drive_inertia_kg_m2`).
    pub fn crankshaft(
        mut end: CrankEnd,
        drive_inertia_kg_m2: f64,
    ) -> Result<Chain, DrivetrainError> {
        end.inertias[0] += drive_inertia_kg_m2;
        reflect(end.names, end.inertias, end.raws, None, end.throws)
    }
}

/// Reflect the chain's inertias and springs to crank speed (see the module's conventions).
fn reflect(
    names: Vec<String>,
    mut inertias: Vec<f64>,
    raws: Vec<Raw>,
    daq: Option<DaqSpec>,
    throws: Vec<usize>,
) -> Result<Chain, DrivetrainError> {
    let n = inertias.len();
    // Speed ratios from the crank back to the motor: a belt's driving side turns 1/ratio as
    // fast as its driven side.
    let mut ratios = vec![1.0; n];
    for i in (0..n - 1).rev() {
        ratios[i] = ratios[i + 1] / raws[i].ratio;
    }
    for (j, r) in inertias.iter_mut().zip(&ratios) {
        *j *= r * r;
    }
    let mut rating = None;
    let mut springs = Vec::with_capacity(raws.len());
    for (i, raw) in raws.into_iter().enumerate() {
        let r = ratios[i + 1];
        if let Some(mut rt) = raw.rating {
            if rating.is_some() {
                return Err(err(
                    "elements",
                    "more than one transducer: the chain has one measuring element",
                ));
            }
            rt.spring = i;
            rating = Some(rt);
        }
        springs.push(Spring {
            name: raw.name,
            k: raw.k * r * r,
            c: raw.c * r * r,
            backlash: raw.backlash / r,
            ratio: r,
        });
    }
    Ok(Chain {
        names,
        inertias,
        ratios,
        springs,
        instrument: rating.zip(daq),
        throws,
    })
}

/// One undamped natural mode of the chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct Mode {
    /// Natural frequency, Hz.
    pub frequency_hz: f64,
    /// Node amplitudes (motor first, crank last; the largest magnitude is 1).
    pub shape: Vec<f64>,
    /// Each spring's share of the mode's strain energy (sums to 1).
    pub strain_energy_share: Vec<f64>,
}

impl Chain {
    /// The stiffness matrix of the free chain plus the motor's hold.
    fn stiffness(&self, hold: MotorHold) -> DMatrix<f64> {
        let n = self.inertias.len();
        let mut k = DMatrix::zeros(n, n);
        for (i, s) in self.springs.iter().enumerate() {
            k[(i, i)] += s.k;
            k[(i + 1, i + 1)] += s.k;
            k[(i, i + 1)] -= s.k;
            k[(i + 1, i)] -= s.k;
        }
        if let MotorHold::Pi { ki, .. } = hold {
            k[(0, 0)] += ki * self.ratios[0] * self.ratios[0];
        }
        k
    }

    /// The damping matrix (springs' dampers plus the PI drive's proportional term).
    fn damping(&self, hold: MotorHold) -> DMatrix<f64> {
        let n = self.inertias.len();
        let mut c = DMatrix::zeros(n, n);
        for (i, s) in self.springs.iter().enumerate() {
            c[(i, i)] += s.c;
            c[(i + 1, i + 1)] += s.c;
            c[(i, i + 1)] -= s.c;
            c[(i + 1, i)] -= s.c;
        }
        if let MotorHold::Pi { kp, .. } = hold {
            c[(0, 0)] += kp * self.ratios[0] * self.ratios[0];
        }
        c
    }

    /// The free nodes of a hold: all but the motor when the motor's speed is prescribed.
    fn free(&self, hold: MotorHold) -> std::ops::Range<usize> {
        match hold {
            MotorHold::Prescribed => 1..self.inertias.len(),
            MotorHold::Pi { .. } => 0..self.inertias.len(),
        }
    }

    /// The undamped modes, lowest first (a rigid-body mode of a free chain, 0 Hz, included),
    /// from `K v = w^2 M v` through the symmetric form `M^-1/2 K M^-1/2`.
    pub fn modes(&self, hold: MotorHold) -> Vec<Mode> {
        let free = self.free(hold);
        let k_all = self.stiffness(hold);
        let m = free.len();
        let k = k_all.view((free.start, free.start), (m, m)).clone_owned();
        let inv_sqrt: Vec<f64> = self.inertias[free.clone()]
            .iter()
            .map(|j| 1.0 / j.sqrt())
            .collect();
        let a = DMatrix::from_fn(m, m, |i, j| k[(i, j)] * inv_sqrt[i] * inv_sqrt[j]);
        let eig = SymmetricEigen::new(a);
        let mut modes: Vec<Mode> = (0..m)
            .map(|q| {
                let lambda = eig.eigenvalues[q].max(0.0);
                let mut shape = vec![0.0; self.inertias.len()];
                for (i, node) in free.clone().enumerate() {
                    shape[node] = eig.eigenvectors[(i, q)] * inv_sqrt[i];
                }
                self.mode(lambda.sqrt() / std::f64::consts::TAU, shape)
            })
            .collect();
        modes.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
        modes
    }

    /// A mode from its frequency and raw shape: the shape scaled to a largest magnitude of 1
    /// (positive at the crank where it moves), and each spring's strain-energy share.
    fn mode(&self, frequency_hz: f64, mut shape: Vec<f64>) -> Mode {
        let big = shape.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        let sign = match shape.last() {
            Some(v) if *v < 0.0 => -1.0,
            _ => 1.0,
        };
        if big > 0.0 {
            shape.iter_mut().for_each(|v| *v = *v * sign / big + 0.0);
        }
        let energies: Vec<f64> = self
            .springs
            .iter()
            .enumerate()
            .map(|(i, s)| 0.5 * s.k * (shape[i + 1] - shape[i]).powi(2))
            .collect();
        let total: f64 = energies.iter().sum();
        let strain_energy_share = energies
            .iter()
            .map(|e| if total > 0.0 { e / total } else { 0.0 })
            .collect();
        Mode {
            frequency_hz,
            shape,
            strain_energy_share,
        }
    }

    /// The steady harmonic response to a torque `F e^{i w t}` at the crank node (complex
    /// amplitude `force`, N m, at crank speed) at circular frequency `omega` (rad/s): each
    /// node's complex angle amplitude, rad (the motor's 0 when prescribed). At `omega = 0` the
    /// static twist under a constant torque (a free chain has no static solution: `None`).
    pub fn harmonic(
        &self,
        hold: MotorHold,
        force: Complex<f64>,
        omega: f64,
    ) -> Option<Vec<Complex<f64>>> {
        let free = self.free(hold);
        let m = free.len();
        let (k, c) = (self.stiffness(hold), self.damping(hold));
        let a = DMatrix::from_fn(m, m, |i, j| {
            let (p, q) = (i + free.start, j + free.start);
            let mass = if p == q { self.inertias[p] } else { 0.0 };
            Complex::new(k[(p, q)] - omega * omega * mass, omega * c[(p, q)])
        });
        let mut b = DVector::from_element(m, Complex::new(0.0, 0.0));
        // An elastic crankshaft's torque shared equally by its throws.
        let share = 1.0 / self.throws.len().max(1) as f64;
        for node in &self.throws {
            if *node >= free.start {
                b[node - free.start] += force * share;
            }
        }
        let x = a.lu().solve(&b)?;
        let mut out = vec![Complex::new(0.0, 0.0); self.inertias.len()];
        for (i, node) in free.enumerate() {
            out[node] = x[i];
        }
        Some(out)
    }

    /// The linear chain's state transition over `period` seconds (the free nodes' angles, then
    /// their speeds, about a common rotation), `exp(A T)` with `A = [0 I; -M^-1 K -M^-1 C]`:
    /// how a deviation from the periodic state returns after one cycle.
    pub fn monodromy(&self, hold: MotorHold, period: f64) -> DMatrix<f64> {
        let free = self.free(hold);
        let m = free.len();
        let (k, c) = (self.stiffness(hold), self.damping(hold));
        let mut a = DMatrix::zeros(2 * m, 2 * m);
        for i in 0..m {
            a[(i, m + i)] = 1.0;
            let inv = 1.0 / self.inertias[free.start + i];
            for j in 0..m {
                let (p, q) = (free.start + i, free.start + j);
                a[(m + i, j)] = -k[(p, q)] * inv;
                a[(m + i, m + j)] = -c[(p, q)] * inv;
            }
        }
        (a * period).exp()
    }

    /// The torque spring `i` carries (at crank speed, from node `i` towards node `i + 1`) at
    /// node angles `phi` and speeds `w`: its spring through the play, plus its damper.
    #[inline]
    pub fn spring_torque(&self, i: usize, phi: &[f64], w: &[f64]) -> f64 {
        let s = &self.springs[i];
        let twist = phi[i] - phi[i + 1];
        let half = 0.5 * s.backlash;
        let elastic = if twist > half {
            s.k * (twist - half)
        } else if twist < -half {
            s.k * (twist + half)
        } else {
            0.0
        };
        elastic + s.c * (w[i] - w[i + 1])
    }

    /// The chain's strain energy at node angles `phi`, J.
    pub fn strain_energy(&self, phi: &[f64]) -> f64 {
        self.springs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let twist = (phi[i] - phi[i + 1]).abs() - 0.5 * s.backlash;
                if twist > 0.0 {
                    0.5 * s.k * twist * twist
                } else {
                    0.0
                }
            })
            .sum()
    }

    /// The spring whose torque measures the chain: the transducer's, or without one the
    /// drive's (the first).
    pub fn measured_spring(&self) -> usize {
        self.instrument.as_ref().map_or(0, |(r, _)| r.spring)
    }

    /// The torque in the measured element itself (N m, not reflected) from its reflected
    /// torque.
    #[inline]
    pub fn transducer_torque(&self, reflected_nm: f64) -> f64 {
        reflected_nm / self.springs[self.measured_spring()].ratio
    }
}

/// A node of the chain in a modal report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct NodeReport {
    /// The node's name (`motor`, an inertia element's name, `crank`).
    pub name: String,
    /// Inertia at crank speed, kg m^2.
    pub inertia_kg_m2: f64,
}

/// A spring of the chain in a modal report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct SpringReport {
    /// The element's name.
    pub name: String,
    /// The two nodes it joins.
    pub between: [String; 2],
    /// Stiffness at crank speed, N m/rad.
    pub stiffness_nm_per_rad: f64,
    /// Viscous damping at crank speed, N m s/rad (the modes are undamped; the runs use it).
    pub damping_nm_s_per_rad: f64,
}

/// Where an engine order crosses a mode: the crank speed at which `order` times the
/// rotational frequency equals the mode's frequency.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct Crossing {
    /// Engine order (excitations per crank revolution).
    pub order: f64,
    /// Crank speed, rpm.
    pub speed_rpm: f64,
}

/// A mode in a modal report: its frequency, shape, the spring that stores most of its strain
/// energy, and the orders that cross it inside the rig's plateau speeds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct ModeReport {
    /// Natural frequency, Hz.
    pub frequency_hz: f64,
    /// Node amplitudes (largest 1), in node order.
    pub shape: Vec<f64>,
    /// Each spring's share of the strain energy.
    pub strain_energy_share: Vec<f64>,
    /// The spring with the largest share.
    pub dominant_spring: String,
    /// Orders 0.5-12 (every half order) crossing it between the lowest and highest plateau.
    pub crossings: Vec<Crossing>,
}

/// The linearised chain and its modes, all at crank speed: what `tribo modes --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct ModalReport {
    /// The rig's name.
    pub rig: String,
    /// How the motor is held: `prescribed` (a fixed node) or `pi` (its controller's spring).
    pub motor_hold: String,
    /// Nodes, motor first, crank last (its cycle-mean inertia).
    pub inertias: Vec<NodeReport>,
    /// Springs between neighbouring nodes.
    pub springs: Vec<SpringReport>,
    /// Elastic modes, lowest first (a free chain's rigid-body mode left out).
    pub modes: Vec<ModeReport>,
    /// The rig's plateau speeds, rpm.
    pub plateaus_rpm: Vec<f64>,
}

/// The engine orders a Campbell diagram shows: 0.5 to 12 in half orders.
pub fn campbell_orders() -> Vec<f64> {
    (1..=24).map(|k| 0.5 * k as f64).collect()
}

impl Chain {
    /// The modal report of the chain held by `hold` on rig `rig` with plateaus `plateaus_rpm`.
    pub fn report(&self, rig: &str, hold: MotorHold, plateaus_rpm: &[f64]) -> ModalReport {
        let (lo, hi) = plateaus_rpm
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let modes = self
            .modes(hold)
            .into_iter()
            .filter(|m| m.frequency_hz > 1e-6)
            .map(|m| {
                let dominant = (0..self.springs.len())
                    .max_by(|a, b| m.strain_energy_share[*a].total_cmp(&m.strain_energy_share[*b]))
                    .map(|i| self.springs[i].name.clone())
                    .unwrap_or_default();
                let crossings = campbell_orders()
                    .into_iter()
                    .map(|order| Crossing {
                        order,
                        speed_rpm: 60.0 * m.frequency_hz / order,
                    })
                    .filter(|c| c.speed_rpm >= lo && c.speed_rpm <= hi)
                    .collect();
                ModeReport {
                    frequency_hz: m.frequency_hz,
                    shape: m.shape,
                    strain_energy_share: m.strain_energy_share,
                    dominant_spring: dominant,
                    crossings,
                }
            })
            .collect();
        ModalReport {
            rig: rig.to_string(),
            motor_hold: match hold {
                MotorHold::Prescribed => "prescribed".into(),
                MotorHold::Pi { .. } => "pi".into(),
            },
            inertias: self
                .names
                .iter()
                .zip(&self.inertias)
                .map(|(n, j)| NodeReport {
                    name: n.clone(),
                    inertia_kg_m2: *j,
                })
                .collect(),
            springs: self
                .springs
                .iter()
                .enumerate()
                .map(|(i, s)| SpringReport {
                    name: s.name.clone(),
                    between: [self.names[i].clone(), self.names[i + 1].clone()],
                    stiffness_nm_per_rad: s.k,
                    damping_nm_s_per_rad: s.c,
                })
                .collect(),
            modes,
            plateaus_rpm: plateaus_rpm.to_vec(),
        }
    }
}

#[cfg(test)]
mod tests;
