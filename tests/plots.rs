//! Every plot Tribo writes, read back from its SVG text and held to the style guide
//! (`host/src/plots.rs`, module doc): the legend in a box beside the plot area, one colour and
//! dash pattern per series, translucent fills matched by a legend swatch, error bars where the
//! data declare their noise, share axes from 0, no `-0` tick, units on both axes, titles that
//! fit the rig.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::*;

/// One SVG element: its tag, its attributes and (for `<text>`) its text.
#[derive(Debug, Clone)]
struct Element {
    tag: String,
    attrs: Vec<(String, String)>,
    text: String,
}

impl Element {
    fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }
    fn num(&self, name: &str) -> f64 {
        self.attr(name)
            .and_then(|v| v.parse().ok())
            .unwrap_or(f64::NAN)
    }
    fn opacity(&self) -> f64 {
        self.attr("opacity")
            .and_then(|v| v.parse().ok())
            .unwrap_or(1.0)
    }
    /// The vertices of a `<polyline>` or `<polygon>`.
    fn points(&self) -> Vec<(f64, f64)> {
        self.attr("points")
            .unwrap_or("")
            .split_whitespace()
            .filter_map(|p| {
                let (x, y) = p.split_once(',')?;
                Some((x.parse().ok()?, y.parse().ok()?))
            })
            .collect()
    }
}

/// The elements of an SVG document, in order (a reader for what plotters writes: one tag per
/// element, attributes in double quotes, text between `<text ...>` and `</text>`).
fn elements(svg: &str) -> Vec<Element> {
    let mut out = Vec::new();
    for chunk in svg.split('<').skip(1) {
        if chunk.starts_with('/') || chunk.starts_with('?') || chunk.starts_with('!') {
            continue;
        }
        let Some((head, rest)) = chunk.split_once('>') else {
            continue;
        };
        let head = head.trim_end_matches('/');
        let (tag, mut attrs_text) = head.split_once(' ').unwrap_or((head, ""));
        let mut attrs = Vec::new();
        while let Some((name, after)) = attrs_text.split_once("=\"") {
            let Some((value, next)) = after.split_once('"') else {
                break;
            };
            attrs.push((name.trim().to_string(), value.to_string()));
            attrs_text = next;
        }
        out.push(Element {
            tag: tag.to_string(),
            attrs,
            text: if tag == "text" {
                rest.trim().to_string()
            } else {
                String::new()
            },
        });
    }
    out
}

/// An axis-aligned box in pixels: x0, y0, x1, y1.
#[derive(Debug, Clone, Copy)]
struct Bbox(f64, f64, f64, f64);

impl Bbox {
    fn contains(&self, (x, y): (f64, f64), slack: f64) -> bool {
        x >= self.0 - slack && x <= self.2 + slack && y >= self.1 - slack && y <= self.3 + slack
    }
    fn overlaps(&self, o: &Bbox) -> bool {
        self.0 < o.2 && o.0 < self.2 && self.1 < o.3 && o.1 < self.3
    }
}

/// Length of a path through `pts`, pixels.
fn length(pts: &[(f64, f64)]) -> f64 {
    pts.windows(2)
        .map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1))
        .sum()
}

/// Dash lengths of the style guide's patterns (`tribo::plots::DASHES`), pixels.
fn dash_lengths() -> Vec<f64> {
    tribo::plots::DASHES
        .iter()
        .flatten()
        .map(|(on, _)| f64::from(*on))
        .collect()
}

/// What one plot is expected to show.
struct Expect<'a> {
    /// Words the title must contain.
    title_has: &'a [&'a str],
    /// Words the title must not contain.
    title_lacks: &'a [&'a str],
    /// Labels the legend must carry.
    legend: &'a [&'a str],
    /// Series that must each have a (colour, dash) of their own.
    series: usize,
    /// The y axis is a share: its ticks from 0.
    share_axis: bool,
}

impl<'a> Expect<'a> {
    /// A plot with nothing forbidden in its title and an ordinary y axis.
    fn plain(title_has: &'a [&'a str], legend: &'a [&'a str], series: usize) -> Self {
        Expect {
            title_has,
            title_lacks: &[],
            legend,
            series,
            share_axis: false,
        }
    }
}

/// A plot area of a chart: the box of its mesh lines (the translucent grid).
fn plot_areas(els: &[Element]) -> Vec<Bbox> {
    // Each chart's grid: lines drawn translucent; charts split by their vertical extent.
    let mut grids: Vec<Bbox> = Vec::new();
    for e in els.iter().filter(|e| e.tag == "line" && e.opacity() < 1.0) {
        let (x1, y1, x2, y2) = (e.num("x1"), e.num("y1"), e.num("x2"), e.num("y2"));
        let b = Bbox(x1.min(x2), y1.min(y2), x1.max(x2), y1.max(y2));
        match grids
            .iter_mut()
            .find(|g| g.overlaps(&Bbox(b.0 - 1.0, b.1 - 1.0, b.2 + 1.0, b.3 + 1.0)))
        {
            Some(g) => *g = Bbox(g.0.min(b.0), g.1.min(b.1), g.2.max(b.2), g.3.max(b.3)),
            None => grids.push(b),
        }
    }
    grids
}

/// Check one SVG against the style guide; panics naming the file and the rule broken.
fn check(file: &Path, expect: &Expect) {
    let svg = std::fs::read_to_string(file).expect("read svg");
    let name = file.display();
    let els = elements(&svg);
    let areas = plot_areas(&els);
    assert!(!areas.is_empty(), "{name}: no plot area (grid) found");
    let in_plot = |p: (f64, f64)| areas.iter().any(|a| a.contains(p, 1.0));

    // The legend: boxes drawn unfilled in black, none overlapping a plot area.
    let boxes: Vec<Bbox> = els
        .iter()
        .filter(|e| e.tag == "rect" && e.attr("fill") == Some("none"))
        .map(|e| {
            let (x, y) = (e.num("x"), e.num("y"));
            Bbox(x, y, x + e.num("width"), y + e.num("height"))
        })
        .collect();
    assert!(!boxes.is_empty(), "{name}: no legend box");
    for b in &boxes {
        for a in &areas {
            assert!(
                !b.overlaps(a),
                "{name}: legend box {b:?} over the plot area {a:?}"
            );
        }
    }
    let texts: Vec<&Element> = els.iter().filter(|e| e.tag == "text").collect();
    for label in expect.legend {
        let t = texts
            .iter()
            .find(|t| t.text == *label)
            .unwrap_or_else(|| panic!("{name}: no legend entry {label:?}"));
        let at = (t.num("x"), t.num("y"));
        assert!(
            boxes.iter().any(|b| b.contains(at, 0.0)),
            "{name}: legend entry {label:?} at {at:?} outside the legend box"
        );
    }

    // Ticks: never `-0`; on a share axis none below 0.
    for t in &texts {
        let s = t.text.as_str();
        if let Ok(v) = s.parse::<f64>() {
            assert!(
                !(v == 0.0 && s.starts_with('-')),
                "{name}: tick label {s:?}"
            );
        }
    }
    if expect.share_axis {
        for t in texts
            .iter()
            .filter(|t| t.attr("text-anchor") == Some("end"))
        {
            if let Ok(v) = t.text.parse::<f64>() {
                assert!(v >= 0.0, "{name}: share axis tick {v}");
            }
        }
    }

    // Axis titles carry their units: plotters writes the y title rotated and the x title
    // centred with dy="-0.5ex".
    let y_titles: Vec<&&Element> = texts
        .iter()
        .filter(|t| t.attr("transform").is_some_and(|v| v.starts_with("rotate")))
        .collect();
    let x_titles: Vec<&&Element> = texts
        .iter()
        .filter(|t| t.attr("dy") == Some("-0.5ex") && t.attr("text-anchor") == Some("middle"))
        .collect();
    assert!(
        !y_titles.is_empty() && !x_titles.is_empty(),
        "{name}: axis titles missing"
    );
    for t in y_titles.iter().chain(&x_titles) {
        let unit = t
            .text
            .split_once('(')
            .and_then(|(_, r)| r.split_once(')'))
            .map(|(u, _)| u);
        assert!(
            unit.is_some_and(|u| !u.is_empty()),
            "{name}: axis title {:?} without a unit in parentheses",
            t.text
        );
    }

    // The title: the largest text.
    let title = texts
        .iter()
        .max_by(|a, b| a.num("font-size").total_cmp(&b.num("font-size")))
        .map(|t| t.text.clone())
        .unwrap_or_default();
    for w in expect.title_has {
        assert!(title.contains(w), "{name}: title {title:?} lacks {w:?}");
    }
    for w in expect.title_lacks {
        assert!(!title.contains(w), "{name}: title {title:?} has {w:?}");
    }

    // Series: each coloured line in the plot area is solid (one long polyline) or dashed (many
    // polylines of one of the guide's dash lengths); every (colour, dash) pair counts once.
    let dashes = dash_lengths();
    let mut styles: BTreeSet<(String, String)> = BTreeSet::new();
    let mut dash_counts: std::collections::BTreeMap<(String, usize), usize> = Default::default();
    for e in els.iter().filter(|e| e.tag == "polyline") {
        let pts = e.points();
        let stroke = e.attr("stroke").unwrap_or("").to_string();
        if pts.len() < 2 || !pts.iter().all(|p| in_plot(*p)) || is_grey(&stroke) {
            continue;
        }
        let l = length(&pts);
        if l > 2.5 * dashes.iter().fold(0.0_f64, |a, b| a.max(*b)) {
            styles.insert((stroke, "solid".into()));
        } else if let Some(k) = dashes.iter().position(|d| (l - d).abs() <= 1.5) {
            *dash_counts.entry((stroke, k)).or_default() += 1;
        }
    }
    for ((stroke, k), n) in dash_counts {
        if n >= 3 {
            styles.insert((stroke, format!("dash {}", dashes[k])));
        }
    }
    assert!(
        styles.len() >= expect.series,
        "{name}: {} distinct (colour, dash) styles for {} series: {styles:?}",
        styles.len(),
        expect.series
    );

    // Translucent fills in the plot area have a legend swatch of the same fill and opacity.
    for e in els
        .iter()
        .filter(|e| matches!(e.tag.as_str(), "polygon" | "rect") && e.opacity() < 1.0)
    {
        let inside = match e.tag.as_str() {
            "polygon" => e.points().iter().all(|p| in_plot(*p)),
            _ => in_plot((e.num("x"), e.num("y"))),
        };
        if !inside {
            continue;
        }
        let swatch = els.iter().any(|s| {
            s.tag == "rect"
                && s.attr("fill") == e.attr("fill")
                && (s.opacity() - e.opacity()).abs() < 1e-9
                && boxes
                    .iter()
                    .any(|b| b.contains((s.num("x"), s.num("y")), 0.0))
        });
        assert!(
            swatch,
            "{name}: translucent fill {:?} (opacity {}) without a matching legend swatch",
            e.attr("fill"),
            e.opacity()
        );
    }
}

/// A black stroke (axes, walls, totals, error bars): not a series colour (the palette's grey
/// is one).
fn is_grey(stroke: &str) -> bool {
    stroke == "#000000"
}

/// Vertical black polylines inside the plot area (error bars).
fn error_bars(file: &Path) -> usize {
    let svg = std::fs::read_to_string(file).expect("read svg");
    let els = elements(&svg);
    let areas = plot_areas(&els);
    els.iter()
        .filter(|e| e.tag == "polyline" && e.attr("stroke") == Some("#000000"))
        .map(|e| e.points())
        .filter(|p| {
            p.len() == 2
                && p[0].0 == p[1].0
                && p[0].1 != p[1].1
                && p.iter().all(|q| areas.iter().any(|a| a.contains(*q, 1.0)))
        })
        .count()
}

fn tribo_ok(args: &[&str], cwd: &Path) {
    let out = tribo_in(args, cwd);
    assert!(
        out.status.success(),
        "tribo {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The comparison's plots: torque with error bars from the data's declared noise and a band
/// swatch, the stacked contributions, the piston regimes of the single cylinder (shares from 0,
/// not titled as a mean over pistons), and the correlation beside Tribo.
#[test]
fn comparison_plots_follow_the_style_guide() {
    let dir = tempfile::tempdir().expect("tempdir");
    tribo_ok(
        &["compare", "--steady", "--no-cv", "--out", "cmp"],
        dir.path(),
    );
    let out = dir.path().join("cmp");
    let sets = ["fedem-baseline", "stribeck-duty", "mixed-film"];
    check(
        &out.join("torque_vs_speed.svg"),
        &Expect {
            title_has: &["Motoring torque", "crf250r-motored"],
            title_lacks: &[],
            legend: &["fedem-baseline", "stribeck-duty", "mixed-film", "measured"],
            series: sets.len(),
            share_axis: false,
        },
    );
    // The data declare 0.05 N m of noise: one error bar per measured point.
    let data =
        std::fs::read_to_string(workspace().join("rigs/data/crf250r-measured.csv")).expect("data");
    assert!(
        data.contains("# noise_nm:"),
        "the bundled data declare noise"
    );
    let points = data
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .count();
    let bars = error_bars(&out.join("torque_vs_speed.svg"));
    assert!(
        bars >= points && points > 0,
        "{bars} error bars for {points} measured points"
    );
    check(
        &out.join("piston_regimes.svg"),
        &Expect {
            title_has: &["regime", "crf250r-motored"],
            title_lacks: &["pistons", "engine"],
            legend: &["stribeck-duty: boundary", "mixed-film: hydrodynamic"],
            series: 6,
            share_axis: true,
        },
    );
    // Sets whose piston shares coincide (read from comparison.json) are named as coincident,
    // since one draws over the other.
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("comparison.json")).expect("comparison.json"),
    )
    .expect("json");
    let shares = |set: &serde_json::Value| -> Vec<String> {
        set["run"]["plateaus"]
            .as_array()
            .into_iter()
            .flatten()
            .flat_map(|p| p["joints"].as_array().into_iter().flatten())
            .filter(|j| j["joint"].as_str().is_some_and(|n| n.starts_with("piston")))
            .map(|j| j["regime_share"].to_string())
            .collect()
    };
    let listed = json["sets"].as_array().expect("sets");
    let svg = std::fs::read_to_string(out.join("piston_regimes.svg")).expect("svg");
    let mut coincident = 0;
    for a in listed {
        for b in listed {
            let (na, nb) = (a["lawset"].as_str(), b["lawset"].as_str());
            if na != nb && shares(a) == shares(b) && !shares(a).is_empty() {
                coincident += 1;
                let said = format!("same shares as {}", nb.unwrap_or_default());
                assert!(svg.contains(&said), "{na:?}: no `{said}` in the legend");
            }
        }
    }
    assert!(
        coincident > 0,
        "stribeck-duty and mixed-film share their regimes"
    );
    check(
        &out.join("contributions_fedem-baseline.svg"),
        &Expect::plain(&["fedem-baseline"], &["piston (fedem-friction)"], 7),
    );
    check(
        &out.join("correlation_stribeck-duty.svg"),
        &Expect::plain(
            &["FMEP", "stribeck-duty"],
            &["total: Tribo", "total: correlation"],
            6,
        ),
    );
}

/// More series than the palette has colours (3 law sets x 7 speeds): every line still has a
/// colour and dash pattern of its own, and the legend grows with the plot beside it.
#[test]
fn a_mass_sweep_of_21_lines_keeps_every_line_distinct() {
    let dir = tempfile::tempdir().expect("tempdir");
    tribo_ok(
        &[
            "mass-response",
            "--steady",
            "--scales",
            "0.8,1,1.2",
            "--out",
            "mr",
        ],
        dir.path(),
    );
    check(
        &dir.path().join("mr/mass_sweep.svg"),
        &Expect::plain(
            &["rod mass scale"],
            &["fedem-baseline 3000 rpm", "mixed-film 9000 rpm"],
            21,
        ),
    );
}

/// A sweep's plot, `run --fmep`'s two plots and `run --crank-angle`'s friction and bearing-load
/// plots, a law's plot and the Campbell diagram.
#[test]
fn sweep_run_law_and_campbell_plots_follow_the_style_guide() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    tribo_ok(
        &[
            "sweep",
            "--temps",
            "40,75,110",
            "--speeds",
            "3000,6000,9000",
            "--out",
            "sw",
        ],
        d,
    );
    check(
        &d.join("sw/sweep_fedem-baseline.svg"),
        &Expect::plain(
            &["oil temperature", "fedem-baseline"],
            &["40 C", "110 C"],
            3,
        ),
    );
    tribo_ok(
        &[
            "run",
            "crf250r-motored",
            "--lawset",
            "fedem-baseline",
            "--steady",
            "--fmep",
            "fm",
            "--crank-angle",
            "ca",
        ],
        d,
    );
    check(
        &d.join("fm/fmep.svg"),
        &Expect::plain(&["FMEP", "crf250r-motored"], &["total"], 3),
    );
    check(
        &d.join("fm/fmep_correlation.svg"),
        &Expect::plain(
            &["FMEP", "crf250r-motored"],
            &["total: Tribo", "total: correlation"],
            6,
        ),
    );
    check(
        &d.join("ca/friction_vs_angle_6000.svg"),
        &Expect::plain(&["6000 rpm"], &["piston"], 3),
    );
    check(
        &d.join("ca/bearing_loads_6000.svg"),
        &Expect::plain(
            &["6000 rpm"],
            &["big end (crank on rod)", "main bearings (on crank)"],
            2,
        ),
    );
    tribo_ok(&["plot-law", "coulomb", "--out", "law.svg"], d);
    check(
        &d.join("law.svg"),
        &Expect::plain(&["coulomb"], &["200 N, 40 C", "5000 N, 100 C"], 3),
    );
    tribo_ok(&["modes", "crf250r-testbed", "--svg", "campbell.svg"], d);
    let campbell = d.join("campbell.svg");
    check(
        &campbell,
        &Expect::plain(&["Campbell", "crf250r-testbed"], &["red: modes"], 1),
    );
}

/// The style itself: 40 series, all different in (colour, dash); neighbours differ in both.
#[test]
fn forty_series_styles_all_differ() {
    let styles: Vec<_> = (0..40).map(tribo::plots::series_style).collect();
    for (i, a) in styles.iter().enumerate() {
        for b in &styles[i + 1..] {
            assert_ne!(a, b, "{a:?}");
        }
    }
    for w in styles.windows(2) {
        assert!(w[0].color != w[1].color && w[0].dash != w[1].dash, "{w:?}");
    }
}
