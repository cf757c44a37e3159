//! Presenting a run: a readable table, JSON, and CSV tables.

use std::fmt::Write as _;
use std::path::Path;

use crate::output::OutputError;
use crate::sim::RunResult;

/// The plateau table, per-law contributions and the energy balance, for people.
pub fn to_text(r: &RunResult) -> String {
    let mut out = String::new();
    let replayed = match r.replayed_steps {
        0 => String::new(),
        n => format!(" ({n} replayed)"),
    };
    let _ = writeln!(
        out,
        "rig {}  drive {}  steps {}{replayed}  max friction iterations {}",
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
            "{:>10.0} {:>12.2} {:>14} {:>8.1}",
            p.set_speed_rpm,
            p.mean_speed_rpm,
            fixed(p.motoring_torque_nm, 5),
            p.oil_temp_c
        );
    }
    out.push_str(&crankcase_text(r));
    out.push_str(&fmep_text(r));
    if r.plateaus.iter().any(|p| !p.joints.is_empty()) {
        let _ = writeln!(out, "\nper joint and law (friction torque at the crank, N m; power, W; regime shares b/m/h, - where the law reports no regime)");
        for p in &r.plateaus {
            let _ = writeln!(out, "  {:.0} rpm", p.set_speed_rpm);
            for j in &p.joints {
                let _ = writeln!(
                    out,
                    "    {:<10} {:<16} {:>10} {:>10}   {}",
                    j.joint,
                    j.law,
                    fixed(j.friction_torque_nm, 5),
                    fixed(j.power_w, 3),
                    regime_cell(&j.regime_share)
                );
            }
        }
    }
    if r.plateaus.iter().any(|p| !p.groups.is_empty()) {
        let _ = writeln!(
            out,
            "\nper component and per cylinder (friction torque at the crank, N m; power, W)"
        );
        for p in &r.plateaus {
            let _ = writeln!(out, "  {:.0} rpm", p.set_speed_rpm);
            for g in &p.groups {
                let _ = writeln!(
                    out,
                    "    {:<12} {:>10} {:>10}",
                    g.group,
                    fixed(g.friction_torque_nm, 5),
                    fixed(g.power_w, 3)
                );
            }
        }
    }
    let e = &r.energy;
    if e.gas_work_j != 0.0 {
        let _ = writeln!(
            out,
            "\nenergy: motor work {} J = energy change {} J + dissipated {} J + gas work {} J + residual {:.3e} J (relative {:.2e})",
            fixed(e.motor_work_j, 4), fixed(e.mechanical_energy_change_j, 4), fixed(e.dissipated_j, 4), fixed(e.gas_work_j, 4), e.residual_j, e.relative_residual
        );
    } else {
        let _ = writeln!(
            out,
            "\nenergy: motor work {} J = energy change {} J + dissipated {} J + residual {:.3e} J (relative {:.2e})",
            fixed(e.motor_work_j, 4), fixed(e.mechanical_energy_change_j, 4), fixed(e.dissipated_j, 4), e.residual_j, e.relative_residual
        );
    }
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
    fit_width(&out)
}

/// A sealed or vented crankcase's pumping per plateau: the model's loss at the plateau speed,
/// its share of the motoring torque, and the gas torque the run measured (cylinder and
/// crankcase together); empty with an atmospheric crankcase.
pub fn crankcase_text(r: &RunResult) -> String {
    let mut out = String::new();
    if r.plateaus
        .iter()
        .all(|p| p.crankcase_pumping_torque_nm.is_none())
    {
        return out;
    }
    let _ = writeln!(
        out,
        "\ncrankcase pumping (the breather's loss at the set speed; share of the motoring torque;\n  measured gas torque, cylinder and crankcase)"
    );
    let _ = writeln!(
        out,
        "{:>10} {:>14} {:>8} {:>14}",
        "set rpm", "pumping N m", "share", "gas N m"
    );
    for p in &r.plateaus {
        let Some(pumping) = p.crankcase_pumping_torque_nm else {
            continue;
        };
        let share = if p.motoring_torque_nm != 0.0 {
            format!("{:.1}%", 100.0 * pumping / p.motoring_torque_nm)
        } else {
            "-".into()
        };
        let _ = writeln!(
            out,
            "{:>10.0} {:>14} {:>8} {:>14}",
            p.set_speed_rpm,
            fixed(pumping, 5),
            share,
            fixed(p.gas_torque_nm, 5)
        );
    }
    out
}

/// The FMEP breakdown per plateau and component (kPa and bar), with its basis; empty when no
/// law is attached.
pub fn fmep_text(r: &RunResult) -> String {
    let mut out = String::new();
    if r.plateaus.iter().all(|p| p.joints.is_empty()) {
        return out;
    }
    out.push('\n');
    out.push_str(&wrap(
        &format!(
            "FMEP, kPa (bar = kPa / 100); {}, V_d = {:.1} cm^3",
            r.fmep.basis.formula(),
            r.fmep.displacement_m3 * 1e6
        ),
        MAX_COLUMNS,
        "  ",
    ));
    let names: Vec<&str> = r
        .plateaus
        .first()
        .map(|p| p.fmep.components.iter().map(|c| c.joint.as_str()).collect())
        .unwrap_or_default();
    // A row per plateau while the components fit across; an engine's many joints turn the
    // table: a row per component, a column per plateau.
    if 10 + 10 + 8 + 10 * (names.len() + 1) <= MAX_COLUMNS {
        let _ = write!(out, "{:>10} {:>9} {:>7}", "set rpm", "total", "bar");
        for n in &names {
            let _ = write!(out, " {n:>9}");
        }
        let _ = writeln!(out, " {:>9}", "motoring");
        for p in &r.plateaus {
            let f = &p.fmep;
            let _ = write!(
                out,
                "{:>10.0} {:>9} {:>7}",
                p.set_speed_rpm,
                fixed(f.total_kpa, 3),
                fixed(f.total_kpa / 100.0, 4)
            );
            for c in &f.components {
                let _ = write!(out, " {:>9}", fixed(c.kpa, 3));
            }
            let _ = writeln!(out, " {:>9}", fixed(f.motoring_kpa, 3));
        }
        return out;
    }
    let w = names.iter().map(|n| n.len()).chain([9]).max().unwrap_or(9);
    let mut rows: Vec<(String, Vec<f64>)> = vec![(
        "total".into(),
        r.plateaus.iter().map(|p| p.fmep.total_kpa).collect(),
    )];
    for (k, n) in names.iter().enumerate() {
        let v = r
            .plateaus
            .iter()
            .map(|p| p.fmep.components.get(k).map_or(f64::NAN, |c| c.kpa))
            .collect();
        rows.push((n.to_string(), v));
    }
    rows.push((
        "motoring".into(),
        r.plateaus.iter().map(|p| p.fmep.motoring_kpa).collect(),
    ));
    // As many plateaus per table as fit across.
    let per = ((MAX_COLUMNS - w) / 10).max(1);
    for chunk in r.plateaus.chunks(per).enumerate() {
        let (i, plateaus) = chunk;
        let _ = write!(out, "{:>w$}", "set rpm");
        for p in plateaus {
            let _ = write!(out, " {:>9.0}", p.set_speed_rpm);
        }
        out.push('\n');
        for (name, v) in &rows {
            let _ = write!(out, "{name:>w$}");
            for x in &v[i * per..i * per + plateaus.len()] {
                let _ = write!(out, " {:>9}", fixed(*x, 3));
            }
            out.push('\n');
        }
    }
    out
}

/// `text` with every line longer than [`MAX_COLUMNS`] wrapped ([`wrap`]), its continuation
/// indented four spaces more than the line.
pub fn fit_width(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let lead = line.len() - line.trim_start_matches(' ').len();
        out.push_str(&wrap(line, MAX_COLUMNS, &" ".repeat(lead + 4)));
    }
    out
}

/// `fmep.csv`: one row per plateau and component (joint) plus a `total` row per plateau, in
/// kPa and bar, with the basis (`two-stroke`: 2 pi T / V_d, `four-stroke`: 4 pi T / V_d).
pub fn fmep_csv(r: &RunResult) -> std::io::Result<String> {
    let basis = match r.fmep.basis {
        crate::sim::FmepBasis::TwoStroke => "two-stroke",
        crate::sim::FmepBasis::FourStroke => "four-stroke",
    };
    let mut rows = Vec::new();
    for p in &r.plateaus {
        let parts = p
            .fmep
            .components
            .iter()
            .map(|c| (c.joint.as_str(), c.kpa))
            .chain([
                ("total", p.fmep.total_kpa),
                ("motoring", p.fmep.motoring_kpa),
            ]);
        for (name, kpa) in parts {
            // + 0.0: an empty sum is -0.0, written "-0"; zero friction is plain 0.
            let kpa = kpa + 0.0;
            rows.push(vec![
                p.set_speed_rpm.to_string(),
                name.to_string(),
                kpa.to_string(),
                (kpa / 100.0).to_string(),
                basis.to_string(),
            ]);
        }
    }
    csv_text(
        &[
            "set_speed_rpm",
            "component",
            "fmep_kpa",
            "fmep_bar",
            "basis",
        ],
        rows,
    )
}

/// `plateaus.csv` (one row per plateau) and `joints.csv` (one row per plateau and joint) in
/// `dir` (`run --csv`), through the `csv` writer so a law name with a comma or quote stays one
/// field. Numbers are in Rust's shortest round-trip form, as in the JSON. The two files are
/// swapped in together ([`crate::output::ResultDir`]): `dir` never holds one old and one new.
pub fn write_csv(r: &RunResult, dir: &Path) -> Result<(), crate::output::OutputError> {
    let mut out = crate::output::ResultDir::create(dir, "run", "--csv")?;
    let plateaus = r
        .plateaus
        .iter()
        .map(|x| {
            vec![
                x.set_speed_rpm.to_string(),
                x.mean_speed_rpm.to_string(),
                x.motoring_torque_nm.to_string(),
                x.oil_temp_c.to_string(),
                x.viscosity_pa_s.to_string(),
                x.window_s[0].to_string(),
                x.window_s[1].to_string(),
                x.revolutions.to_string(),
            ]
        })
        .collect();
    let p = csv_text(&PLATEAUS_CSV_HEADER, plateaus)
        .map_err(|source| render("plateaus.csv", source))?;
    out.write("plateaus.csv", p.as_bytes())?;
    let mut joints = Vec::new();
    for x in &r.plateaus {
        for l in &x.joints {
            let s = l.regime_share;
            joints.push(vec![
                x.set_speed_rpm.to_string(),
                l.joint.clone(),
                l.law.clone(),
                l.friction_torque_nm.to_string(),
                l.power_w.to_string(),
                l.mean_normal_load_n.to_string(),
                s.none.to_string(),
                s.boundary.to_string(),
                s.mixed.to_string(),
                s.hydrodynamic.to_string(),
            ]);
        }
    }
    let j = csv_text(&JOINTS_CSV_HEADER, joints).map_err(|source| render("joints.csv", source))?;
    out.write("joints.csv", j.as_bytes())?;
    // An engine's totals per component (`main_*`, ...) and per cylinder.
    if r.plateaus.iter().any(|p| !p.groups.is_empty()) {
        let groups = r
            .plateaus
            .iter()
            .flat_map(|x| {
                x.groups.iter().map(|g| {
                    vec![
                        x.set_speed_rpm.to_string(),
                        g.group.clone(),
                        g.friction_torque_nm.to_string(),
                        g.power_w.to_string(),
                    ]
                })
            })
            .collect();
        let header = ["set_speed_rpm", "group", "friction_torque_nm", "power_w"];
        let g = csv_text(&header, groups).map_err(|source| render("groups.csv", source))?;
        out.write("groups.csv", g.as_bytes())?;
    }
    out.commit()
}

/// A table that could not be rendered, naming the file.
pub(crate) fn render(what: &str, error: std::io::Error) -> OutputError {
    OutputError::Render {
        what: what.to_string(),
        error,
    }
}

/// The columns of `plateaus.csv`.
const PLATEAUS_CSV_HEADER: [&str; 8] = [
    "set_speed_rpm",
    "mean_speed_rpm",
    "motoring_torque_nm",
    "oil_temp_c",
    "viscosity_pa_s",
    "window_start_s",
    "window_end_s",
    "revolutions",
];

/// The columns of `joints.csv`.
const JOINTS_CSV_HEADER: [&str; 10] = [
    "set_speed_rpm",
    "joint",
    "law",
    "friction_torque_nm",
    "power_w",
    "mean_normal_load_n",
    "share_none",
    "share_boundary",
    "share_mixed",
    "share_hydrodynamic",
];

/// Units a number is never parted from at a line break (`0.05 N m`, `80 C`, `12 kPa`).
const UNITS: [&str; 18] = [
    "N", "m", "kPa", "Pa", "C", "rpm", "W", "J", "Hz", "cSt", "mPa", "s", "%", "kg", "mm", "um",
    "m/s", "bar",
];

/// The words of `body` with the spaces before each (1 for the first), a number and the unit
/// after it (`0.05 N m`) kept as one word.
fn wrap_tokens(body: &str) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    let mut gap = 0;
    // Whether the last word is a number (or a number with a unit already glued to it).
    let mut after_number = false;
    for word in body.split(' ') {
        if word.is_empty() {
            gap += 1;
            continue;
        }
        let spaces = gap + 1;
        gap = 0;
        let unit = UNITS.contains(&word.trim_end_matches([',', ';', ')', '.', ':']));
        match out.last_mut() {
            Some(last) if after_number && unit && spaces == 1 => {
                last.1.push(' ');
                last.1.push_str(word);
            }
            _ => {
                after_number = false;
                out.push((spaces, word.to_string()));
            }
        }
        let w = word.trim_start_matches(['(', '[', '~', '+', '-']);
        after_number |= w.starts_with(|c: char| c.is_ascii_digit());
        if !unit && !w.starts_with(|c: char| c.is_ascii_digit()) {
            after_number = false;
        }
    }
    out
}

/// `text` broken into lines of at most `width` characters at spaces (its own line breaks
/// kept, and a line that fits left as it is), continuation lines starting with `indent`; a
/// word longer than a line is cut. Words that stay on a line keep the spaces between them, so
/// the columns of a table row stay aligned up to where it breaks.
pub fn wrap(text: &str, width: usize, indent: &str) -> String {
    let mut out = String::new();
    for paragraph in text.split('\n') {
        // A line that fits is kept as it is (its spacing may align columns).
        if paragraph.chars().count() <= width {
            out.push_str(paragraph);
            out.push('\n');
            continue;
        }
        // Leading spaces are the paragraph's own indentation.
        let body = paragraph.trim_start_matches(' ');
        let mut line = paragraph[..paragraph.len() - body.len()].to_string();
        let mut line_w = line.len();
        let mut fresh = true;
        for (spaces, word) in wrap_tokens(body) {
            let chars: Vec<char> = word.chars().collect();
            // The part of the word not yet placed: cutting a long word moves this start, never
            // the characters (a 15 MiB word is cut in time linear in its length).
            let mut word: &[char] = &chars;
            if !fresh && line_w + spaces + word.len() > width {
                out.push_str(&line);
                out.push('\n');
                line = indent.to_string();
                line_w = indent.chars().count();
                fresh = true;
            }
            if !fresh {
                line.extend(std::iter::repeat_n(' ', spaces));
                line_w += spaces;
            }
            // A word that cannot fit on a line of its own is cut.
            while line_w + word.len() > width && width > line_w {
                let take = width - line_w;
                line.extend(&word[..take]);
                out.push_str(&line);
                out.push('\n');
                word = &word[take..];
                line = indent.to_string();
                line_w = indent.chars().count();
            }
            line_w += word.len();
            line.extend(word.iter());
            fresh = false;
        }
        out.push_str(&line);
        out.push('\n');
    }
    out
}

/// A number with `prec` decimals, or `-` where there is none.
fn opt(x: Option<f64>, prec: usize) -> String {
    x.filter(|v| v.is_finite())
        .map_or("-".to_string(), |v| fixed(v, prec))
}

/// `x` with `prec` decimals, never `-0.0`: a value that rounds to zero prints as zero (a
/// reader takes `-0.0` for a small negative number, which it need not be).
pub fn fixed(x: f64, prec: usize) -> String {
    unsigned_zero(format!("{x:.prec$}"))
}

/// `x` with `prec` decimals and its sign (`+1.000`, `-0.500`); a value that rounds to zero
/// prints as `+0.000`, never `-0.000`.
pub fn signed(x: f64, prec: usize) -> String {
    let s = format!("{x:+.prec$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => format!("+{rest}"),
        _ => s,
    }
}

/// A formatted number with a minus sign before nothing but zeros loses the sign.
fn unsigned_zero(s: String) -> String {
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// The widest line any text report prints, in columns: tables are split into blocks of sets
/// and prose is wrapped so that every line fits.
pub const MAX_COLUMNS: usize = 100;

/// Columns `(header, cells)` side by side after a shared left part, split into as many tables
/// as it takes for every line to fit [`MAX_COLUMNS`]: each block is a group of columns under a
/// title, separated by ` | `; the left part (`left_header`, `left_rows`) repeats in every table.
pub(crate) struct Blocks<'a> {
    pub(crate) left_header: [String; 2],
    pub(crate) left_rows: Vec<String>,
    /// Per block: its title and its columns (header, cells right-aligned).
    pub(crate) blocks: Vec<(String, Vec<Column<'a>>)>,
}

/// A column of a [`Blocks`] table: its header and its cells, one per left row.
pub(crate) type Column<'a> = (&'a str, Vec<String>);

impl Blocks<'_> {
    /// The table as text, split into as many tables as it takes to fit [`MAX_COLUMNS`].
    pub(crate) fn render(&self) -> String {
        let left_w = self
            .left_header
            .iter()
            .chain(&self.left_rows)
            .map(|l| l.chars().count())
            .max()
            .unwrap_or(0);
        // Each block's columns at their widest cell; the block as wide as its title needs.
        let laid: Vec<(usize, Vec<usize>)> = self
            .blocks
            .iter()
            .map(|(title, cols)| {
                let widths: Vec<usize> = cols
                    .iter()
                    .map(|(h, cells)| {
                        cells
                            .iter()
                            .map(|c| c.chars().count())
                            .chain([h.chars().count()])
                            .max()
                            .unwrap_or(0)
                    })
                    .collect();
                let inner = widths.iter().sum::<usize>() + widths.len().saturating_sub(1);
                (inner.max(title.chars().count()), widths)
            })
            .collect();
        let mut out = String::new();
        let mut start = 0;
        while start < self.blocks.len() {
            // As many blocks as fit (at least one).
            let mut end = start + 1;
            let mut width = left_w + 3 + laid[start].0;
            while end < self.blocks.len() && width + 3 + laid[end].0 <= MAX_COLUMNS {
                width += 3 + laid[end].0;
                end += 1;
            }
            if start > 0 {
                out.push('\n');
            }
            let mut title = format!("{:<left_w$}", self.left_header[0]);
            let mut head = format!("{:>left_w$}", self.left_header[1]);
            let shown = || laid[start..end].iter().zip(&self.blocks[start..end]);
            for ((w, widths), (block_title, block)) in shown() {
                let _ = write!(title, " | {block_title:<w$}");
                let cols: Vec<String> = block
                    .iter()
                    .zip(widths)
                    .map(|((h, _), cw)| format!("{h:>cw$}"))
                    .collect();
                let _ = write!(head, " | {:>w$}", cols.join(" "));
            }
            out.push_str(title.trim_end());
            out.push('\n');
            out.push_str(&head);
            out.push('\n');
            for (i, l) in self.left_rows.iter().enumerate() {
                let mut row = format!("{l:>left_w$}");
                for ((w, widths), (_, block)) in shown() {
                    let cols: Vec<String> = block
                        .iter()
                        .zip(widths)
                        .map(|((_, cells), cw)| {
                            format!("{:>cw$}", cells.get(i).map_or("", String::as_str))
                        })
                        .collect();
                    let _ = write!(row, " | {:>w$}", cols.join(" "));
                }
                out.push_str(&row);
                out.push('\n');
            }
            start = end;
        }
        out
    }
}

/// A law set's name with its calibration status where it is not the plain case.
/// A law's regime shares as `b/m/h` (boundary, mixed, hydrodynamic); `-` for a law that
/// reports no regime over the whole cycle (it has none to report, not a share of zero each).
fn regime_cell(s: &crate::sim::RegimeShare) -> String {
    if s.boundary + s.mixed + s.hydrodynamic <= 0.0 {
        "-".into()
    } else {
        format!(
            "{}/{}/{}",
            fixed(s.boundary, 2),
            fixed(s.mixed, 2),
            fixed(s.hydrodynamic, 2)
        )
    }
}

/// A set's place in the ranking: `2`, or `2=` when tied with another.
fn rank_label(s: &crate::study::SetResult) -> String {
    if s.tie.is_some() {
        format!("{}=", s.rank)
    } else {
        s.rank.to_string()
    }
}

/// One line per group of tied sets (`ranked` in ranking order): which sets the data cannot
/// tell apart, and why.
fn ties_text(ranked: &[&crate::study::SetResult]) -> String {
    let mut out = String::new();
    let mut seen: Vec<&str> = Vec::new();
    for s in ranked {
        let Some(tie) = &s.tie else { continue };
        if seen.contains(&s.lawset.as_str()) {
            continue;
        }
        seen.push(&s.lawset);
        seen.extend(tie.with.iter().map(String::as_str));
        let mut names = vec![s.lawset.clone()];
        names.extend(tie.with.iter().cloned());
        let why = if tie.same_torques {
            format!(
                "the same torque within {} N m at every point",
                crate::study::SAME_TORQUE_NM
            )
        } else {
            "different torques, but scores within the noise".to_string()
        };
        out.push_str(&wrap(
            &format!(
                "  {}= {}: indistinguishable on these data: {why} (ranking errors {:.1e} N m apart, less than the data's noise of {} N m)",
                s.rank,
                names.join(", "),
                tie.error_spread_nm,
                fixed(tie.noise_nm, 3)
            ),
            MAX_COLUMNS,
            "      ",
        ));
    }
    out
}

/// One line per set that leaves joints without a law the other sets cover: its ranking
/// compares a torque missing those joints' friction.
fn uncovered_text(ranked: &[&crate::study::SetResult]) -> String {
    let mut out = String::new();
    for s in ranked.iter().filter(|s| !s.uncovered_joints.is_empty()) {
        out.push_str(&wrap(
            &format!(
                "  {} {}: NO LAW on {} (other sets put one there): its torque lacks that friction, so its place is not like for like",
                rank_label(s),
                s.lawset,
                s.uncovered_joints.join(", ")
            ),
            MAX_COLUMNS,
            "      ",
        ));
    }
    out
}

fn set_title(s: &crate::study::SetResult) -> String {
    match s.calibration.status {
        crate::study::CalibrationStatus::NotFitted => format!("{} (not fitted)", s.lawset),
        _ => s.lawset.clone(),
    }
}

/// The side-by-side table with each set's 95% band, the verdict, the out-of-sample scores and
/// ranking, the fitted values, validation scores, and per-joint contributions (joints as rows,
/// speeds as columns). Every line fits [`MAX_COLUMNS`].
pub fn comparison_text(c: &crate::study::Comparison) -> String {
    let mut out = String::new();
    out.push_str(&wrap(
        &format!("rig {}  data {}  mode {}", c.rig, c.data_file, c.mode),
        MAX_COLUMNS,
        "  ",
    ));
    out.push('\n');
    let blocks = Blocks {
        left_header: [String::new(), format!("{:>7} {:>9}", "rpm", "measured")],
        left_rows: c
            .data
            .iter()
            .map(|d| format!("{:>7.0} {:>9.3}", d.speed_rpm, d.torque_nm))
            .collect(),
        blocks: c
            .sets
            .iter()
            .map(|s| {
                let n = c.data.len();
                let model: Vec<String> = (0..n)
                    .map(|i| {
                        let m = s
                            .run
                            .plateaus
                            .get(i)
                            .map_or(f64::NAN, |p| p.motoring_torque_nm);
                        format!("{m:.3}")
                    })
                    .collect();
                let error: Vec<String> = (0..n)
                    .map(|i| signed(s.errors_nm.get(i).copied().unwrap_or(f64::NAN), 3))
                    .collect();
                let band: Vec<String> = (0..n)
                    .map(|i| match (&s.band_lower_nm, &s.band_upper_nm) {
                        (Some(lo), Some(hi)) => match (lo.get(i), hi.get(i)) {
                            (Some(l), Some(h)) => format!("{l:.3}-{h:.3}"),
                            _ => "-".into(),
                        },
                        _ => "-".into(),
                    })
                    .collect();
                (
                    set_title(s),
                    vec![("model", model), ("error", error), ("95% band", band)],
                )
            })
            .collect(),
    };
    out.push_str(&blocks.render());
    let _ = writeln!(
        out,
        "(N m; 95% band: the model torque's 95% confidence band from its fitted parameters, on a\n log scale so it stays above zero)"
    );
    for s in c.sets.iter().filter(|s| s.band_lower_nm.is_none()) {
        if let Some(why) = &s.band_note {
            out.push_str(&wrap(
                &format!(" - no band for {}: {why}", s.lawset),
                MAX_COLUMNS,
                "   ",
            ));
        }
    }
    out.push_str(&comparison_fmep(c));
    out.push('\n');
    out.push_str(&wrap(
        &format!("Verdict: {}.", c.verdict.sentence),
        MAX_COLUMNS,
        "  ",
    ));
    out.push('\n');
    out.push_str(&wrap(
        &format!("scores, ranked by {}", c.ranked_by),
        MAX_COLUMNS,
        "",
    ));
    let mut ranked: Vec<&crate::study::SetResult> = c.sets.iter().collect();
    ranked.sort_by_key(|s| s.rank);
    let name_w = ranked
        .iter()
        .map(|s| set_title(s).chars().count())
        .chain([7])
        .max()
        .unwrap_or(7)
        // The numbers take 76 columns: a longer title goes on a line of its own.
        .min(MAX_COLUMNS - 76);
    let _ = writeln!(
        out,
        "{:>4}  {:<name_w$} {:>6} {:>6} {:>8} {:>8} {:>11} {:>7} {:>7} {:>9}",
        "rank",
        "law set",
        "params",
        "points",
        "RMSE",
        "LOO RMSE",
        "max |error|",
        "AICc",
        "BIC",
        "+10C max"
    );
    for s in &ranked {
        let title = set_title(s);
        let (rank, title) = if title.chars().count() > name_w {
            let _ = writeln!(out, "{:>4}  {title}", s.rank);
            (String::new(), String::new())
        } else {
            (rank_label(s), title)
        };
        let _ = writeln!(
            out,
            "{:>4}  {:<name_w$} {:>6} {:>6} {:>8.3} {:>8} {:>11.3} {:>7} {:>7} {:>8}%{}",
            rank,
            title,
            if s.scores.prior_fitted_params > 0 {
                format!("0+{}", s.scores.prior_fitted_params)
            } else {
                s.calibration.params.len().to_string()
            },
            s.scores.points,
            s.rmse_nm,
            opt(s.scores.cv_rmse_nm, 3),
            s.max_abs_error_nm,
            opt(s.scores.aicc, 1),
            opt(s.scores.bic, 1),
            signed(s.temperature_response.max_rise_percent_per_10c, 1),
            if s.temperature_response.max_rise_percent_per_10c
                > crate::score::TEMPERATURE_RISE_FLAG_PERCENT
            {
                "!"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        out,
        "  (RMSE in N m: RMSE in sample, LOO RMSE out of sample; params: free parameters, fitted\n   to these data before scoring unless marked not fitted, + numbers tuned to these data\n   elsewhere; AICc and BIC count those and the noise variance, lower is better; +10C max:\n   largest torque change per 10 C of oil warming, ! above 10%; 1=: tied, see below)"
    );
    out.push_str(&ties_text(&ranked));
    out.push_str(&uncovered_text(&ranked));
    for s in &ranked {
        if s.calibration.params.is_empty() {
            continue;
        }
        let what = match s.calibration.status {
            crate::study::CalibrationStatus::Fitted => "fitted",
            _ => "not fitted, the file's values",
        };
        let values: Vec<String> = s
            .calibration
            .params
            .iter()
            .map(|p| {
                let short = p.id.rsplit('.').next().unwrap_or(&p.id);
                let state = match (&p.at_bound, p.std_dev) {
                    (Some(side), _) => format!(" (on its {side} bound, held there)"),
                    (None, Some(sd)) => format!(" +- {sd:.2e}"),
                    (None, None) => String::new(),
                };
                format!("{short} = {:.4e}{state}", p.value)
            })
            .collect();
        out.push_str(&wrap(
            &format!("  {} {what}: {}", s.lawset, values.join(", ")),
            MAX_COLUMNS,
            "      ",
        ));
    }
    for s in &ranked {
        let mut notes: Vec<String> = Vec::new();
        if s.band_wider_than_data == Some(true) {
            notes.push("its 95% band is wider than the spread of the measured torques: these data do not determine its prediction".into());
        }
        notes.extend(s.scores.notes.iter().cloned());
        // A parameter on its bound is already marked so in the fitted values above.
        notes.extend(
            s.uncertainty
                .statements
                .iter()
                .filter(|n| !(n.contains("on their bound") || n.contains("is on its bound")))
                .cloned(),
        );
        for v in &s.validation {
            notes.push(format!(
                "validation data {}: RMSE {:.3} N m, max |error| {:.3} N m over {} points",
                v.file,
                v.rmse_nm,
                v.max_abs_error_nm,
                v.measured_nm.len()
            ));
        }
        for n in notes {
            out.push_str(&wrap(
                &format!("  {}: {n}", s.lawset),
                MAX_COLUMNS,
                "      ",
            ));
        }
    }
    out.push_str("\nper-joint contributions (friction torque at the crank, N m)\n");
    for s in &c.sets {
        out.push_str(&joint_table(s));
        for w in &s.run.warnings {
            out.push_str(&wrap(&format!("  warning: {w}"), MAX_COLUMNS, "    "));
        }
    }
    fit_width(&out)
}

/// One law set's per-joint friction torques: a row per joint and law, a column per speed, so
/// the table's width grows with the speeds (8 characters each), not with the laws.
fn joint_table(s: &crate::study::SetResult) -> String {
    let mut out = String::new();
    let Some(first) = s.run.plateaus.first() else {
        return out;
    };
    let labels: Vec<String> = first
        .joints
        .iter()
        .map(|j| format!("{}:{}", j.joint, j.law))
        .collect();
    let w = labels
        .iter()
        .map(|l| l.len())
        .max()
        .unwrap_or(0)
        .max(s.lawset.len() + 2);
    let _ = write!(out, "  {:<w$}", s.lawset);
    for p in &s.run.plateaus {
        let _ = write!(out, " {:>7.0}", p.set_speed_rpm);
    }
    out.push('\n');
    for (k, l) in labels.iter().enumerate() {
        let _ = write!(out, "  {l:<w$}");
        for p in &s.run.plateaus {
            let v = p.joints.get(k).map_or(f64::NAN, |j| j.friction_torque_nm);
            let _ = write!(out, " {:>7}", fixed(v, 4));
        }
        out.push('\n');
    }
    out
}

/// CSV text from a header and rows (through the `csv` writer, so names with commas or quotes
/// stay one field).
pub(crate) fn csv_text(header: &[&str], rows: Vec<Vec<String>>) -> std::io::Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header).map_err(std::io::Error::other)?;
    for r in rows {
        w.write_record(&r).map_err(std::io::Error::other)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| std::io::Error::other(e.to_string()))?;
    String::from_utf8(bytes).map_err(std::io::Error::other)
}

/// The comparison's FMEP column: model FMEP (all laws, kPa) per speed and law set, with the
/// basis of the first set's run.
fn comparison_fmep(c: &crate::study::Comparison) -> String {
    let mut out = String::new();
    let Some(first) = c.sets.first() else {
        return out;
    };
    let blocks = Blocks {
        left_header: [String::new(), format!("{:>7} {:>9}", "rpm", "measured")],
        left_rows: c
            .data
            .iter()
            .map(|d| {
                format!(
                    "{:>7.0} {:>9.2}",
                    d.speed_rpm,
                    first.run.fmep.kpa(d.torque_nm)
                )
            })
            .collect(),
        blocks: c
            .sets
            .iter()
            .map(|s| {
                let cells = (0..c.data.len())
                    .map(|i| {
                        let v = s.run.plateaus.get(i).map_or(f64::NAN, |p| p.fmep.total_kpa);
                        format!("{v:.2}")
                    })
                    .collect();
                (s.lawset.clone(), vec![("FMEP", cells)])
            })
            .collect(),
    };
    out.push('\n');
    out.push_str(&blocks.render());
    out.push_str(&wrap(
        &format!(
            "(FMEP, kPa: {}, V_d = {:.1} cm^3; measured: the measured torque converted the same way)",
            first.run.fmep.basis.formula(),
            first.run.fmep.displacement_m3 * 1e6
        ),
        MAX_COLUMNS,
        " ",
    ));
    out
}

fn cell(x: Option<f64>) -> String {
    x.map_or(String::new(), |v| v.to_string())
}

/// `comparison.csv`: one row per speed and law set, with the leave-one-out error and the band.
pub fn comparison_csv(c: &crate::study::Comparison) -> std::io::Result<String> {
    let mut rows = Vec::new();
    for s in &c.sets {
        for (i, d) in c.data.iter().enumerate() {
            if let Some(p) = s.run.plateaus.get(i) {
                rows.push(vec![
                    d.speed_rpm.to_string(),
                    d.torque_nm.to_string(),
                    d.oil_temp_c.to_string(),
                    s.lawset.clone(),
                    p.motoring_torque_nm.to_string(),
                    s.errors_nm[i].to_string(),
                    p.mean_speed_rpm.to_string(),
                    cell(s.scores.cv_errors_nm.get(i).copied().flatten()),
                    cell(s.band_lower_nm.as_ref().and_then(|b| b.get(i).copied())),
                    cell(s.band_upper_nm.as_ref().and_then(|b| b.get(i).copied())),
                    cell(s.temperature_response.percent_per_10c.get(i).copied()),
                    p.fmep.total_kpa.to_string(),
                ]);
            }
        }
    }
    csv_text(
        &[
            "speed_rpm",
            "measured_torque_nm",
            "oil_temp_c",
            "lawset",
            "model_torque_nm",
            "error_nm",
            "mean_speed_rpm",
            "loo_error_nm",
            "band95_lower_nm",
            "band95_upper_nm",
            "torque_change_percent_per_10c",
            "model_fmep_kpa",
        ],
        rows,
    )
}

/// `scores.csv`: one row per law set: ranking, free parameters, in-sample and cross-validated
/// RMSE, AIC, AICc, BIC, and the validation RMSE of each `--validate` file.
pub fn scores_csv(c: &crate::study::Comparison) -> std::io::Result<String> {
    let rows = c
        .sets
        .iter()
        .map(|s| {
            vec![
                s.lawset.clone(),
                s.rank.to_string(),
                s.scores.free_params.to_string(),
                s.scores.prior_fitted_params.to_string(),
                s.scores.points.to_string(),
                s.rmse_nm.to_string(),
                cell(s.scores.cv_rmse_nm),
                s.max_abs_error_nm.to_string(),
                cell(s.scores.aic),
                cell(s.scores.aicc),
                cell(s.scores.bic),
                s.calibration.status.as_str().to_string(),
                s.band_wider_than_data
                    .map_or(String::new(), |b| b.to_string()),
                s.band_note.clone().unwrap_or_default(),
                s.temperature_response.max_rise_percent_per_10c.to_string(),
                s.validation
                    .iter()
                    .map(|v| format!("{}={}", v.file, v.rmse_nm))
                    .collect::<Vec<_>>()
                    .join(";"),
            ]
        })
        .collect();
    csv_text(
        &[
            "lawset",
            "rank",
            "free_params",
            "prior_fitted_params",
            "points",
            "rmse_nm",
            "loo_rmse_nm",
            "max_abs_error_nm",
            "aic",
            "aicc",
            "bic",
            "calibration",
            "band_wider_than_data",
            "band_note",
            "max_torque_rise_percent_per_10c",
            "validation_rmse_nm",
        ],
        rows,
    )
}

/// `validation.csv`: every law set's prediction of every `--validate` point (header only when
/// none was given).
pub fn validation_csv(c: &crate::study::Comparison) -> std::io::Result<String> {
    let mut rows = Vec::new();
    for s in &c.sets {
        for v in &s.validation {
            for i in 0..v.measured_nm.len() {
                rows.push(vec![
                    s.lawset.clone(),
                    v.file.clone(),
                    v.speeds_rpm[i].to_string(),
                    v.oil_temp_c[i].to_string(),
                    v.measured_nm[i].to_string(),
                    v.model_nm[i].to_string(),
                    v.errors_nm[i].to_string(),
                ]);
            }
        }
    }
    csv_text(
        &[
            "lawset",
            "file",
            "speed_rpm",
            "oil_temp_c",
            "measured_torque_nm",
            "model_torque_nm",
            "error_nm",
        ],
        rows,
    )
}

/// The calibration report: values with intervals and bounds, residuals per run, the
/// out-of-sample scores, how the optimiser stopped, and every warning.
pub fn fit_text(r: &crate::fit::FitResult) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "law set {}: {} parameter(s), {} points in {} run(s), {} model evaluations ({} failed)\nstopped: {}\n",
        r.lawset,
        r.params.len(),
        r.measured_nm.len(),
        r.runs.len(),
        r.evaluations,
        r.failed_evaluations,
        r.termination
    );
    let w = r
        .params
        .iter()
        .map(|p| p.len())
        .chain([9])
        .max()
        .unwrap_or(9);
    let _ = writeln!(
        out,
        "{:<w$} {:>10} {:>10} {:>9} {:>21}  bounds",
        "parameter", "start", "fitted", "1 sigma", "95% interval"
    );
    for i in 0..r.params.len() {
        let interval = r.uncertainty.interval95.get(i).copied().flatten().map_or(
            match &r.at_bound[i] {
                Some(side) => format!("ON {side} BOUND"),
                None => "not determined".to_string(),
            },
            |[a, b]| format!("[{a:.3e}, {b:.3e}]"),
        );
        let _ = writeln!(
            out,
            "{:<w$} {:>10.4e} {:>10.4e} {:>9} {:>21}  [{:.2e}, {:.2e}]",
            r.params[i],
            r.start[i],
            r.values[i],
            r.std_dev[i].map_or("-".to_string(), |s| format!("{s:.2e}")),
            interval,
            r.bounds[i][0],
            r.bounds[i][1]
        );
    }
    for run in &r.runs {
        let _ = writeln!(
            out,
            "\nrun {}: RMSE {:.4} N m\n{:>7} {:>6} {:>10} {:>10} {:>10} {:>13}",
            run.file, run.rmse_nm, "rpm", "oil C", "measured", "model", "residual", "95% band"
        );
        for i in 0..run.speeds_rpm.len() {
            let band = match (&run.band_lower_nm, &run.band_upper_nm) {
                (Some(lo), Some(hi)) => format!("{:.3}-{:.3}", lo[i], hi[i]),
                _ => "-".to_string(),
            };
            let _ = writeln!(
                out,
                "{:>7.0} {:>6.1} {:>10.3} {:>10.3} {:>+10.4} {:>13}",
                run.speeds_rpm[i],
                run.oil_temp_c[i],
                run.measured_nm[i],
                run.model_nm[i],
                run.residuals_nm[i],
                band
            );
        }
    }
    if r.runs.iter().any(|run| run.band_lower_nm.is_some()) {
        let _ = writeln!(
            out,
            "(95% band: the model torque's confidence band from the fitted parameters' covariance, on a\n log scale so it stays above zero)"
        );
    }
    let sc = &r.scores;
    let _ = writeln!(
        out,
        "\nRMSE {:.4} N m in sample, {} N m leave-one-out ({} free parameters, {} points); AICc {}, BIC {}",
        r.rmse_nm,
        opt(sc.cv_rmse_nm, 4),
        sc.free_params,
        sc.points,
        opt(sc.aicc, 2),
        opt(sc.bic, 2)
    );
    for v in &r.validation {
        let _ = writeln!(
            out,
            "validation {}: RMSE {:.4} N m, max |error| {:.4} N m",
            v.file, v.rmse_nm, v.max_abs_error_nm
        );
    }
    if r.starts.len() > 1 {
        let _ = writeln!(out, "\nstart points:");
        for s in &r.starts {
            let _ = writeln!(
                out,
                "  {:<16} RMSE {:>8}  {}",
                s.kind,
                opt(s.rmse_nm, 4),
                s.termination
            );
        }
    }
    for w in &r.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    fit_width(&out)
}

/// The mass-response tables. The FEDEM thesis's change (table 10.6 minus 10.5) is a column
/// only beside the thesis's own law set, labelled as the thesis's; other law sets have none.
pub fn mass_text(r: &[crate::study::MassResponse]) -> String {
    let scales = |set: &crate::study::MassResponse| {
        let mut v: Vec<f64> = Vec::new();
        for c in &set.changes {
            if !v.contains(&c.scale) {
                v.push(c.scale);
            }
        }
        v
    };
    if r.iter().any(|set| scales(set).len() > 1) {
        return mass_sweep_text(r);
    }
    let mut out = String::new();
    for set in r {
        let thesis = set.changes.iter().any(|c| c.fedem_change_nm.is_some());
        let body = match set.body {
            crate::study::ScaledBody::Rod => "rod mass and inertia",
            crate::study::ScaledBody::Piston => "piston assembly mass",
            crate::study::ScaledBody::Crank => "crankshaft mass and inertia",
        };
        let _ = writeln!(
            out,
            "law set {}: {body} scaled; motoring torque and its change, N m",
            set.lawset
        );
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
                let _ = writeln!(
                    out,
                    "        {:<10} {:<16} change {:>9} N m   mean normal load change {:>9} N",
                    j.joint,
                    j.law,
                    signed(j.change_nm, 5),
                    signed(j.normal_load_change_n, 2)
                );
            }
        }
        // The column explained under the table that has it, not after a user's set.
        if thesis {
            out.push_str(&wrap(
                "FEDEM thesis (T 10.6-10.5): the change the thesis's own FEDEM model gave for the rod at 60% (its table 10.6 minus table 10.5, N m), shown beside the thesis's law set only.",
                MAX_COLUMNS,
                "  ",
            ));
        }
        out.push('\n');
    }
    fit_width(&out)
}

/// A sweep of scale factors: per law set one table of the motoring torque's change in percent,
/// speeds as rows and scale factors as columns; the per-joint changes are in the CSV and JSON.
fn mass_sweep_text(r: &[crate::study::MassResponse]) -> String {
    let mut out = String::new();
    for set in r {
        let mut scales: Vec<f64> = Vec::new();
        let mut speeds: Vec<f64> = Vec::new();
        for c in &set.changes {
            if !scales.contains(&c.scale) {
                scales.push(c.scale);
            }
            if !speeds.contains(&c.speed_rpm) {
                speeds.push(c.speed_rpm);
            }
        }
        let body = match set.body {
            crate::study::ScaledBody::Rod => "rod mass and inertia",
            crate::study::ScaledBody::Piston => "piston assembly mass",
            crate::study::ScaledBody::Crank => "crankshaft mass and inertia",
        };
        out.push_str(&wrap(
            &format!(
                "law set {}: {body} scaled; change of the motoring torque from scale 1, % (columns: scale factor)",
                set.lawset
            ),
            MAX_COLUMNS,
            "  ",
        ));
        let _ = write!(out, "{:>7} {:>9}", "rpm", "at 1, N m");
        for sc in &scales {
            let _ = write!(out, " {:>7}", format!("x{sc}"));
        }
        out.push('\n');
        for rpm in &speeds {
            let at = |sc: f64| {
                set.changes
                    .iter()
                    .find(|c| c.speed_rpm == *rpm && c.scale == sc)
            };
            let original = scales
                .iter()
                .find_map(|sc| at(*sc))
                .map_or(f64::NAN, |c| c.original_nm);
            let _ = write!(out, "{rpm:>7.0} {:>9}", fixed(original, 4));
            for sc in &scales {
                let cell = at(*sc).map_or("-".to_string(), |c| {
                    signed(100.0 * c.change_nm / c.original_nm, 2)
                });
                let _ = write!(out, " {cell:>7}");
            }
            out.push('\n');
        }
        out.push('\n');
    }
    out.push_str(&wrap(
        "per speed, scale and joint (the change of each law's friction torque and of the joint's mean normal load): mass_response.csv, mass_response_joints.csv, mass_response.json",
        MAX_COLUMNS,
        "  ",
    ));
    fit_width(&out)
}

/// `mass_response.csv`: one row per law set, scale factor and speed, the motoring torque at
/// scale 1 and scaled, its change in N m and %, and the thesis's FEDEM change where it has one.
pub fn mass_csv(r: &[crate::study::MassResponse]) -> std::io::Result<String> {
    let rows = r
        .iter()
        .flat_map(|set| {
            set.changes.iter().map(move |c| {
                vec![
                    set.lawset.clone(),
                    format!("{:?}", set.body).to_lowercase(),
                    c.scale.to_string(),
                    c.speed_rpm.to_string(),
                    c.original_nm.to_string(),
                    c.scaled_nm.to_string(),
                    c.change_nm.to_string(),
                    (100.0 * c.change_nm / c.original_nm).to_string(),
                    c.fedem_change_nm.map_or(String::new(), |f| f.to_string()),
                ]
            })
        })
        .collect();
    csv_text(
        &[
            "lawset",
            "body",
            "scale",
            "speed_rpm",
            "original_nm",
            "scaled_nm",
            "change_nm",
            "change_percent",
            "fedem_thesis_change_nm",
        ],
        rows,
    )
}

/// `mass_response_joints.csv`: one row per law set, scale factor, speed, joint and law.
pub fn mass_joints_csv(r: &[crate::study::MassResponse]) -> std::io::Result<String> {
    let rows = r
        .iter()
        .flat_map(|set| {
            set.changes.iter().flat_map(move |c| {
                c.joints.iter().map(move |j| {
                    vec![
                        set.lawset.clone(),
                        c.scale.to_string(),
                        c.speed_rpm.to_string(),
                        j.joint.clone(),
                        j.law.clone(),
                        j.original_nm.to_string(),
                        j.scaled_nm.to_string(),
                        j.change_nm.to_string(),
                        j.normal_load_change_n.to_string(),
                    ]
                })
            })
        })
        .collect();
    csv_text(
        &[
            "lawset",
            "scale",
            "speed_rpm",
            "joint",
            "law",
            "original_nm",
            "scaled_nm",
            "change_nm",
            "normal_load_change_n",
        ],
        rows,
    )
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
                let _ = write!(out, " {:>9}", fixed(set.torque(k, i, n), 4));
            }
            out.push('\n');
        }
        out.push_str(&viscosity_response_text(s, set));
        for w in &set.warnings {
            let _ = writeln!(out, "warning: {w}");
        }
    }
    fit_width(&out)
}

/// The law set's torque response to the oil's viscosity between neighbouring temperatures,
/// `d ln T / d ln mu = ln(T_a / T_b) / ln(mu_a / mu_b)` per speed: 1 for a Petroff film at a
/// fixed temperature, 0 for viscosity-blind friction (boundary contact, a rolling bearing's
/// load term). Measured engines respond weakly (docs/engines.md, "Oil temperature"), so this
/// is printed beside every sweep of two temperatures or more.
fn viscosity_response_text(s: &crate::study::Sweep, set: &crate::study::SweepSet) -> String {
    let mut out = String::new();
    let n = s.speeds_rpm.len();
    let pairs: Vec<usize> = (1..s.temps_c.len())
        .filter(|&k| {
            let (a, b) = (s.viscosities_pa_s[k - 1], s.viscosities_pa_s[k]);
            a > 0.0 && b > 0.0 && (a / b).ln().abs() > 1e-9
        })
        .collect();
    if pairs.is_empty() {
        return out;
    }
    let _ = writeln!(out, "viscosity response d ln T / d ln mu");
    let _ = write!(out, "{:>7}", "rpm");
    for &k in &pairs {
        let _ = write!(
            out,
            " {:>9}",
            format!("{}-{}", s.temps_c[k - 1], s.temps_c[k])
        );
    }
    out.push('\n');
    for (i, rpm) in s.speeds_rpm.iter().enumerate() {
        let _ = write!(out, "{rpm:>7.0}");
        for &k in &pairs {
            let (ta, tb) = (set.torque(k - 1, i, n), set.torque(k, i, n));
            let mu = (s.viscosities_pa_s[k - 1] / s.viscosities_pa_s[k]).ln();
            let r = if ta > 0.0 && tb > 0.0 {
                (ta / tb).ln() / mu
            } else {
                f64::NAN
            };
            let _ = write!(out, " {r:>9.3}");
        }
        out.push('\n');
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
    // The rig's joints, as every point lists them (the single-cylinder rig's five when the
    // sweep has no point).
    let joints: Vec<String> = s
        .sets
        .iter()
        .flat_map(|set| set.points.first())
        .map(|p| p.joints.iter().map(|j| j.joint.clone()).collect())
        .next()
        .unwrap_or_else(|| {
            crate::rig::JOINT_NAMES
                .iter()
                .map(|j| j.to_string())
                .collect()
        });
    header.extend(joints.iter().map(|j| format!("{j}_friction_nm")));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{EnergyBalance, LawResult, PlateauResult, RegimeShare};

    /// A table row longer than the width breaks at its end, its columns as they were; a
    /// number is never parted from its unit at a break, wherever the break falls.
    #[test]
    fn wrap_keeps_columns_and_units_together() {
        let row = format!(
            "{:<20} {:>10} {:>10} {}",
            "piston.law.mu_b",
            "1.5e-1",
            "2.0e-1",
            "x ".repeat(40)
        );
        let out = wrap(&row, 60, "    ");
        let first = out.lines().next().expect("a line");
        let columns = row.split(" x").next().expect("columns");
        assert!(first.starts_with(columns), "{out}");
        for width in 20..60 {
            let text = "the spread is 0.05 N m at 3000 rpm and 80 C, above 12 kPa ".repeat(2);
            let out = wrap(&text, width, "  ");
            for line in out.lines() {
                let t = line.trim_start();
                assert!(
                    !["N m", "m ", "rpm", "C,", "kPa"]
                        .iter()
                        .any(|u| t.starts_with(u)),
                    "width {width}: a unit starts a line: {out}"
                );
            }
        }
    }

    /// A law without regimes shows `-`, not shares of zero; a share of zero of a law with
    /// regimes is printed.
    #[test]
    fn a_law_without_regimes_shows_a_dash() {
        let none = RegimeShare {
            none: 1.0,
            ..Default::default()
        };
        assert_eq!(regime_cell(&none), "-");
        let some = RegimeShare {
            none: 0.0,
            boundary: 0.0,
            mixed: 0.25,
            hydrodynamic: 0.75,
        };
        assert_eq!(regime_cell(&some), "0.00/0.25/0.75");
    }

    fn result_with_law(law: &str) -> RunResult {
        let joint = LawResult {
            joint: "piston".into(),
            law: law.into(),
            friction_torque_nm: 0.25,
            power_w: 78.5,
            mean_normal_load_n: 120.0,
            regime_share: RegimeShare {
                none: 0.0,
                boundary: 0.5,
                mixed: 0.25,
                hydrodynamic: 0.25,
            },
        };
        RunResult {
            rig: "test rig".into(),
            drive: tribo_core::sim::DriveKind::Prescribed,
            plateaus: vec![PlateauResult {
                set_speed_rpm: 3000.0,
                mean_speed_rpm: 2999.5,
                motoring_torque_nm: 0.1 + 0.2,
                oil_temp_c: 80.0,
                viscosity_pa_s: 0.0248,
                window_s: [2.4, 2.5],
                revolutions: 5,
                joints: vec![joint],
                gas_torque_nm: 0.0,
                crankcase_pumping_torque_nm: None,
                fmep: Default::default(),
                groups: Vec::new(),
                correlation: None,
                instrument: None,
            }],
            fmep: Default::default(),
            energy_residual_j: 0.0,
            energy: EnergyBalance {
                motor_work_j: 1.0,
                mechanical_energy_change_j: 0.0,
                dissipated_j: 1.0,
                gas_work_j: 0.0,
                residual_j: 0.0,
                relative_residual: 0.0,
            },
            steps: 1,
            rejected_steps: 0,
            replayed_steps: 0,
            max_friction_iterations: 1,
            warnings: Vec::new(),
            law_time: Vec::new(),
        }
    }

    #[test]
    fn wrap_keeps_lines_that_fit_and_breaks_the_others_within_the_width() {
        // A table row that fits keeps its alignment.
        assert_eq!(wrap("a    b", 10, "  "), "a    b\n");
        let long = "  alpha beta gamma delta epsilon zeta eta theta iota kappa";
        let w = wrap(long, 20, "    ");
        for line in w.lines() {
            assert!(line.chars().count() <= 20, "{line:?}");
        }
        assert!(w.starts_with("  alpha beta gamma\n    delta"), "{w}");
        // Every word survives, in order.
        let words: Vec<&str> = w.split_whitespace().collect();
        assert_eq!(words, long.split_whitespace().collect::<Vec<_>>());
        // A word longer than a line is cut into pieces that fit.
        let w = wrap(&"x".repeat(45), 20, "  ");
        assert!(w.lines().all(|l| l.chars().count() <= 20), "{w}");
        assert_eq!(w.chars().filter(|c| *c == 'x').count(), 45);
        // Its own line breaks are kept.
        assert_eq!(wrap("one\ntwo", 10, ""), "one\ntwo\n");
    }

    #[test]
    fn run_csv_files_keep_the_plain_format_for_ordinary_names() {
        let dir = tempfile::tempdir().expect("temporary directory");
        write_csv(&result_with_law("stribeck-duty"), dir.path()).expect("CSV written");
        let plateaus = std::fs::read_to_string(dir.path().join("plateaus.csv")).expect("read");
        assert_eq!(
            plateaus,
            "set_speed_rpm,mean_speed_rpm,motoring_torque_nm,oil_temp_c,viscosity_pa_s,window_start_s,window_end_s,revolutions\n\
             3000,2999.5,0.30000000000000004,80,0.0248,2.4,2.5,5\n"
        );
        let joints = std::fs::read_to_string(dir.path().join("joints.csv")).expect("read");
        assert_eq!(
            joints,
            "set_speed_rpm,joint,law,friction_torque_nm,power_w,mean_normal_load_n,share_none,share_boundary,share_mixed,share_hydrodynamic\n\
             3000,piston,stribeck-duty,0.25,78.5,120,0,0.5,0.25,0.25\n"
        );
    }

    #[test]
    fn a_law_name_with_a_comma_or_quote_stays_one_csv_field() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let name = "odd,law \"v2\"";
        write_csv(&result_with_law(name), dir.path()).expect("CSV written");
        let mut reader = csv::Reader::from_path(dir.path().join("joints.csv")).expect("open");
        let rows: Vec<csv::StringRecord> = reader
            .records()
            .collect::<Result<_, _>>()
            .expect("valid CSV");
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].len(), JOINTS_CSV_HEADER.len());
        assert_eq!(&rows[0][2], name);
        assert_eq!(&rows[0][3], "0.25");
    }
}
