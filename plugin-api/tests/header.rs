//! The C header (`include/tribo_law.h`) and the Fortran module (`include/tribo_law.f90`) against
//! the Rust contract (`src/contract.rs`): every struct, every field's offset and size, and every
//! constant.
//!
//! The test reads the header itself: each `typedef struct` and each `#define TRIBO_*` found there
//! is printed by a generated C program (offsetof, sizeof) and a generated Fortran program (c_loc
//! differences, c_sizeof) and compared with the Rust definitions. So a field or constant added to
//! the header and not to Rust (or to the Fortran module) fails here, and the Rust field lists
//! below are exhaustive patterns, so a field added to a Rust struct does not compile until it is
//! listed. Needs `cc` (or `$CC`) and `gfortran` (or `$FC`): `.ci/setup-toolchains` installs them.

use std::collections::BTreeMap;
use std::mem::{offset_of, size_of};

use std::path::{Path, PathBuf};
use std::process::Command;
use tribo_plugin_api::contract::v1::LawInput as V1Input;
use tribo_plugin_api::contract::v2::{LawInput as V2Input, LawOutput as V2Output};

use tribo_plugin_api::contract::{CLawDescription, CParamSpec};
use tribo_plugin_api::{
    BearingType, InnerBody, JointKind, LawInput, LawOutput, Regime, AFFINE_IN_LOAD,
    CONTRACT_VERSION, HAS_ASPERITY_SHARE, HAS_COEFFICIENT, HAS_DERIVATIVE, HAS_DUTY_PARAMETER,
    HAS_ECCENTRICITY, HAS_LOAD_DERIVATIVE, HAS_MIN_FILM, HAS_PEAK_PRESSURE, SUITS_PLAIN,
    SUITS_ROLLING, SUITS_SLIDE,
};

/// Offset and size of one field.
type Layout = BTreeMap<String, (usize, usize)>;

fn include_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("include")
}

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("header-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the scratch directory");
    dir
}

fn run(cmd: &mut Command, what: &str) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start {cmd:?} ({e}); run .ci/setup-toolchains"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{what} failed:\n{stderr}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn tool(var: &str, default: &str) -> String {
    std::env::var(var).unwrap_or_else(|_| default.into())
}

/// The header's structs (name, field names in order) and constants (name, value), read from
/// the text: comments removed, then `typedef struct NAME { TYPE FIELD; ... } NAME;` and
/// `#define TRIBO_NAME VALUEu`.
struct Header {
    structs: Vec<(String, Vec<String>)>,
    constants: Vec<(String, u64)>,
}

fn without_comments(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("/*") {
        out.push_str(&rest[..start]);
        let end = rest[start..].find("*/").expect("comments are closed") + start + 2;
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

fn parse_header() -> Header {
    parse_header_in(&include_dir())
}

/// The `tribo_law.h` of directory `dir` (the current one, or the frozen version 1).
fn parse_header_in(dir: &Path) -> Header {
    let text = std::fs::read_to_string(dir.join("tribo_law.h")).expect("read header");
    let code = without_comments(&text);
    let mut structs = Vec::new();
    let mut rest = code.as_str();
    while let Some(at) = rest.find("typedef struct ") {
        rest = &rest[at + "typedef struct ".len()..];
        let open = rest.find('{').expect("struct body");
        let name = rest[..open].trim().to_string();
        let close = rest.find('}').expect("struct end");
        let fields = rest[open + 1..close]
            .split(';')
            .map(str::trim)
            .filter(|d| !d.is_empty())
            .map(|d| {
                let last = d.split_whitespace().last().expect("a declaration");
                last.trim_start_matches('*').to_string()
            })
            .collect();
        structs.push((name, fields));
        rest = &rest[close..];
    }
    let constants = code
        .lines()
        .filter_map(|l| l.trim().strip_prefix("#define "))
        .filter_map(|d| {
            let mut parts = d.split_whitespace();
            let name = parts.next()?;
            let value = parts.next()?.strip_suffix('u')?.parse().ok()?;
            Some((name.to_string(), value))
        })
        .collect();
    Header { structs, constants }
}

/// Size of the field a projection picks.
fn field_size<T, F>(_: fn(&T) -> &F) -> usize {
    size_of::<F>()
}

/// `(C name, Rust type, [fields])`: the size, and each field's offset and size, keyed as the
/// generated programs print them. The closure's struct pattern is exhaustive, so every Rust
/// field must be listed.
macro_rules! rust_layout {
    ($map:ident, $c:literal, $t:ident, [$($f:ident),+ $(,)?]) => {{
        let _every_field_is_listed = |v: $t| {
            let $t { $($f: _),+ } = v;
        };
        $map.insert(format!("{}.size", $c), (size_of::<$t>(), 0));
        $(
            $map.insert(
                format!("{}.{}", $c, stringify!($f)),
                (offset_of!($t, $f), field_size(|s: &$t| &s.$f)),
            );
        )+
    }};
}

fn rust_structs() -> Layout {
    let mut m = Layout::new();
    rust_layout!(
        m,
        "tribo_law_input",
        LawInput,
        [
            joint_kind,
            reserved,
            relative_velocity,
            sliding_velocity_m_s,
            normal_load_n,
            reaction_x_n,
            reaction_y_n,
            reaction_moment_nm,
            contact_radius_m,
            contact_length_m,
            oil_temp_c,
            viscosity_pa_s,
            engine_speed_rad_s,
            crank_angle_rad,
            time_s,
            dt_s,
            cylinder_pressure_pa,
            crankcase_pressure_pa,
            piston_from_tdc_m,
            cycle_angle_rad,
            body_a_angle,
            body_a_velocity,
            body_b_angle,
            body_b_velocity,
            inner_body,
            bearing_type,
            load_on_inner_x_n,
            load_on_inner_y_n,
        ]
    );
    rust_layout!(
        m,
        "tribo_law_output",
        LawOutput,
        [
            force,
            coefficient,
            duty_parameter,
            dforce_dvelocity,
            regime,
            flags,
            dforce_dload,
            min_film_m,
            eccentricity_x,
            eccentricity_y,
            peak_pressure_pa,
            asperity_share,
        ]
    );
    rust_layout!(
        m,
        "tribo_param_spec",
        CParamSpec,
        [name, unit, doc, default_value, min, max]
    );
    rust_layout!(
        m,
        "tribo_law_description",
        CLawDescription,
        [name, version, summary, n_params, params]
    );
    m
}

fn rust_constants() -> BTreeMap<String, u64> {
    // Exhaustive matches: a new variant does not compile until it is given its C name here.
    let joint = |k: JointKind| match k {
        JointKind::Revolute => ("TRIBO_JOINT_REVOLUTE", k as u64),
        JointKind::Prismatic => ("TRIBO_JOINT_PRISMATIC", k as u64),
    };
    let regime = |r: Regime| match r {
        Regime::None => ("TRIBO_REGIME_NONE", r as u64),
        Regime::Boundary => ("TRIBO_REGIME_BOUNDARY", r as u64),
        Regime::Mixed => ("TRIBO_REGIME_MIXED", r as u64),
        Regime::Hydrodynamic => ("TRIBO_REGIME_HYDRODYNAMIC", r as u64),
    };
    let bearing = |b: BearingType| match b {
        BearingType::Unspecified => ("TRIBO_BEARING_UNSPECIFIED", b as u64),
        BearingType::Plain => ("TRIBO_BEARING_PLAIN", b as u64),
        BearingType::Rolling => ("TRIBO_BEARING_ROLLING", b as u64),
        BearingType::Slide => ("TRIBO_BEARING_SLIDE", b as u64),
    };
    let inner = |i: InnerBody| match i {
        InnerBody::A => ("TRIBO_INNER_BODY_A", i as u64),
        InnerBody::B => ("TRIBO_INNER_BODY_B", i as u64),
    };
    let mut m: BTreeMap<String, u64> = [
        joint(JointKind::Revolute),
        joint(JointKind::Prismatic),
        regime(Regime::None),
        regime(Regime::Boundary),
        regime(Regime::Mixed),
        regime(Regime::Hydrodynamic),
        bearing(BearingType::Unspecified),
        bearing(BearingType::Plain),
        bearing(BearingType::Rolling),
        bearing(BearingType::Slide),
        inner(InnerBody::A),
        inner(InnerBody::B),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    for (name, value) in [
        ("TRIBO_LAW_CONTRACT_VERSION", CONTRACT_VERSION),
        ("TRIBO_HAS_COEFFICIENT", HAS_COEFFICIENT),
        ("TRIBO_HAS_DUTY_PARAMETER", HAS_DUTY_PARAMETER),
        ("TRIBO_HAS_DERIVATIVE", HAS_DERIVATIVE),
        ("TRIBO_HAS_LOAD_DERIVATIVE", HAS_LOAD_DERIVATIVE),
        ("TRIBO_HAS_MIN_FILM", HAS_MIN_FILM),
        ("TRIBO_HAS_ECCENTRICITY", HAS_ECCENTRICITY),
        ("TRIBO_HAS_PEAK_PRESSURE", HAS_PEAK_PRESSURE),
        ("TRIBO_HAS_ASPERITY_SHARE", HAS_ASPERITY_SHARE),
        ("TRIBO_AFFINE_IN_LOAD", AFFINE_IN_LOAD),
        ("TRIBO_SUITS_PLAIN", SUITS_PLAIN),
        ("TRIBO_SUITS_ROLLING", SUITS_ROLLING),
        ("TRIBO_SUITS_SLIDE", SUITS_SLIDE),
    ] {
        m.insert(name.into(), u64::from(value));
    }
    m
}

/// `key offset size` and `NAME value` lines into maps.
fn read_printed(text: &str) -> (Layout, BTreeMap<String, u64>) {
    let (mut layout, mut constants) = (Layout::new(), BTreeMap::new());
    for line in text.lines() {
        let parts: Vec<&str> = line.split_whitespace().collect();
        let num = |s: &str| -> usize { s.parse().unwrap_or_else(|_| panic!("`{line}`")) };
        match parts.as_slice() {
            [key, off, size] => {
                layout.insert((*key).to_string(), (num(off), num(size)));
            }
            [key, size] if key.ends_with(".size") => {
                layout.insert((*key).to_string(), (num(size), 0));
            }
            [key, value] => {
                constants.insert((*key).to_string(), num(value) as u64);
            }
            _ => panic!("unexpected line `{line}`"),
        }
    }
    (layout, constants)
}

/// Every key on both sides with equal values; the message lists each difference.
fn assert_same<V: PartialEq + std::fmt::Debug>(
    what: &str,
    foreign: &BTreeMap<String, V>,
    rust: &BTreeMap<String, V>,
) {
    let mut diffs = Vec::new();
    for (k, v) in rust {
        match foreign.get(k) {
            None => diffs.push(format!("{k}: in Rust ({v:?}), missing from {what}")),
            Some(f) if f != v => diffs.push(format!("{k}: {what} {f:?}, Rust {v:?}")),
            Some(_) => {}
        }
    }
    for (k, v) in foreign {
        if !rust.contains_key(k) {
            diffs.push(format!("{k}: in {what} ({v:?}), missing from Rust"));
        }
    }
    assert!(
        diffs.is_empty(),
        "{what} and Rust disagree:\n{}",
        diffs.join("\n")
    );
}

fn c_program(h: &Header) -> String {
    let mut s = String::from(
        "#include <stddef.h>\n#include <stdio.h>\n#include \"tribo_law.h\"\nint main(void) {\n",
    );
    for (name, fields) in &h.structs {
        s += &format!("    printf(\"{name}.size %zu\\n\", sizeof({name}));\n");
        for f in fields {
            s += &format!(
                "    printf(\"{name}.{f} %zu %zu\\n\", offsetof({name}, {f}), sizeof((({name} *)0)->{f}));\n"
            );
        }
    }
    for (name, _) in &h.constants {
        s += &format!("    printf(\"{name} %llu\\n\", (unsigned long long){name});\n");
    }
    s + "    return 0;\n}\n"
}

fn fortran_program(h: &Header) -> String {
    let mut decl = String::new();
    let mut body = String::new();
    for (i, (name, fields)) in h.structs.iter().enumerate() {
        decl += &format!("  type({name}), target :: v{i}\n");
        body += &format!("  print '(a, 1x, i0)', '{name}.size', c_sizeof(v{i})\n");
        for f in fields {
            body += &format!(
                "  print '(a, 1x, i0, 1x, i0)', '{name}.{f}', &\n    off(c_loc(v{i}%{f}), c_loc(v{i})), c_sizeof(v{i}%{f})\n"
            );
        }
    }
    for (name, _) in &h.constants {
        body += &format!("  print '(a, 1x, i0)', '{name}', {name}\n");
    }
    format!(
        "program layout\n  use, intrinsic :: iso_c_binding\n  use tribo_law\n  implicit none\n{decl}{body}\
         contains\n  integer(c_intptr_t) function off(field, whole)\n    type(c_ptr), intent(in) :: field, whole\n\
         \x20   off = transfer(field, 0_c_intptr_t) - transfer(whole, 0_c_intptr_t)\n  end function off\n\
         end program layout\n"
    )
}

#[test]
fn the_header_declares_every_struct_and_constant_of_the_rust_contract() {
    let h = parse_header();
    let names: Vec<&str> = h.structs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "tribo_law_input",
            "tribo_law_output",
            "tribo_param_spec",
            "tribo_law_description"
        ],
        "the structs of tribo_law.h"
    );
    let header_constants: BTreeMap<String, u64> = h.constants.iter().cloned().collect();
    assert_same("tribo_law.h", &header_constants, &rust_constants());
}

/// Compile and run the layout program of header `h` from include directory `include`.
fn c_layout(h: &Header, include: &Path, name: &str) -> (Layout, BTreeMap<String, u64>) {
    let dir = scratch(name);
    let src = dir.join("layout.c");
    std::fs::write(&src, c_program(h)).expect("write the C program");
    let exe = dir.join("layout");
    run(
        Command::new(tool("CC", "cc"))
            .args(["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-I"])
            .arg(include)
            .arg(&src)
            .arg("-o")
            .arg(&exe),
        "compiling the C layout program",
    );
    read_printed(&run(&mut Command::new(&exe), "the C layout program"))
}

/// The input and output fields of contract version 2 (and, for the input, version 1).
macro_rules! v2_input_fields {
    ($m:ident, $t:ident, [$($more:ident),*]) => {
        rust_layout!(
            $m,
            "tribo_law_input",
            $t,
            [
                joint_kind,
                reserved,
                relative_velocity,
                sliding_velocity_m_s,
                normal_load_n,
                reaction_x_n,
                reaction_y_n,
                reaction_moment_nm,
                contact_radius_m,
                contact_length_m,
                oil_temp_c,
                viscosity_pa_s,
                engine_speed_rad_s,
                crank_angle_rad,
                time_s,
                dt_s,
                $($more),*
            ]
        )
    };
}

/// A frozen header (`tests/fixtures/c/vN`, as released) lays its structs out exactly as the
/// host's frozen types for that version (`frozen`), each field where the current structs have
/// it, so a law built from it reads and writes the values it always did; it says `version`.
fn check_frozen_header(version: u64, frozen: &Layout) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../tests/fixtures/c/v{version}"));
    let h = parse_header_in(&dir);
    let (layout, constants) = c_layout(&h, &dir, &format!("c-v{version}"));
    let of_frozen_structs: Layout = layout
        .iter()
        .filter(|(k, _)| k.starts_with("tribo_law_input.") || k.starts_with("tribo_law_output."))
        .map(|(k, v)| (k.clone(), *v))
        .collect();
    assert_same(
        &format!("the version-{version} header"),
        &of_frozen_structs,
        frozen,
    );
    let current = rust_structs();
    for (key, at) in frozen {
        if !key.ends_with(".size") {
            assert_eq!(
                current.get(key),
                Some(at),
                "{key} moved after version {version}"
            );
        }
    }
    assert_eq!(constants.get("TRIBO_LAW_CONTRACT_VERSION"), Some(&version));
    // Every constant it has kept its value; the other structs did not change.
    let now = rust_constants();
    for (name, value) in &constants {
        if name != "TRIBO_LAW_CONTRACT_VERSION" {
            assert_eq!(
                now.get(name),
                Some(value),
                "{name} changed after version {version}"
            );
        }
    }
    for (key, at) in &layout {
        if !of_frozen_structs.contains_key(key) {
            assert_eq!(
                current.get(key),
                Some(at),
                "{key} changed after version {version}"
            );
        }
    }
}

/// Contract version 2's output, as `contract::v2::LawOutput` (also version 1's).
fn v2_output(m: &mut Layout) {
    rust_layout!(
        m,
        "tribo_law_output",
        V2Output,
        [
            force,
            coefficient,
            duty_parameter,
            dforce_dvelocity,
            regime,
            flags
        ]
    );
}

/// The frozen version-1 header: its input is `contract::v1::LawInput`, the prefix of the
/// current input the host hands a version-1 law; its output is version 2's.
#[test]
fn the_frozen_v1_header_matches_the_v1_prefix_of_the_contract() {
    let mut v1 = Layout::new();
    v2_input_fields!(v1, V1Input, []);
    v2_output(&mut v1);
    check_frozen_header(1, &v1);
}

/// The frozen version-2 header: its input is `contract::v2::LawInput` and its output
/// `contract::v2::LawOutput`, the prefixes of the current structs.
#[test]
fn the_frozen_v2_header_matches_the_v2_prefix_of_the_contract() {
    let mut v2 = Layout::new();
    v2_input_fields!(
        v2,
        V2Input,
        [
            cylinder_pressure_pa,
            crankcase_pressure_pa,
            piston_from_tdc_m,
            cycle_angle_rad
        ]
    );
    v2_output(&mut v2);
    check_frozen_header(2, &v2);
}

#[test]
fn c_header_layout_and_constants_match_the_rust_contract() {
    let (layout, constants) = c_layout(&parse_header(), &include_dir(), "c");
    assert_same("the C header", &layout, &rust_structs());
    assert_same("the C header", &constants, &rust_constants());
}

#[test]
fn fortran_module_layout_and_constants_match_the_rust_contract() {
    let h = parse_header();
    let dir = scratch("fortran");
    let src = dir.join("layout.f90");
    std::fs::write(&src, fortran_program(&h)).expect("write the Fortran program");
    let exe = dir.join("layout");
    run(
        Command::new(tool("FC", "gfortran"))
            .args(["-std=f2008", "-Wall", "-Werror", "-J"])
            .arg(&dir)
            .arg(include_dir().join("tribo_law.f90"))
            .arg(&src)
            .arg("-o")
            .arg(&exe),
        "compiling the Fortran layout program against tribo_law.f90",
    );
    let (layout, constants) = read_printed(&run(
        Command::new(&exe).current_dir(&dir),
        "the Fortran layout program",
    ));
    assert_same("the Fortran module", &layout, &rust_structs());
    assert_same("the Fortran module", &constants, &rust_constants());
}

#[test]
fn the_header_compiles_cleanly_as_c_and_as_cpp() {
    let dir = scratch("compile");
    for (compiler, std, file) in [
        (tool("CC", "cc"), "-std=c99", "use.c"),
        (tool("CXX", "c++"), "-std=c++11", "use.cpp"),
    ] {
        let src = dir.join(file);
        // A definition with the header's prototype: C++ must see it as extern "C" (no mangling).
        std::fs::write(
            &src,
            "#include \"tribo_law.h\"\nuint32_t tribo_law_contract_version(void) { return TRIBO_LAW_CONTRACT_VERSION; }\n",
        )
        .expect("write");
        let obj = dir.join(format!("{file}.o"));
        run(
            Command::new(&compiler)
                .args([std, "-Wall", "-Wextra", "-pedantic", "-Werror", "-c", "-I"])
                .arg(include_dir())
                .arg(&src)
                .arg("-o")
                .arg(&obj),
            &format!("{compiler} {std} on tribo_law.h"),
        );
        let symbols = run(Command::new("nm").arg(&obj), "nm");
        assert!(
            symbols
                .lines()
                .any(|l| l.ends_with(" T tribo_law_contract_version")),
            "{compiler}: the symbol is not exported unmangled:\n{symbols}"
        );
    }
}
