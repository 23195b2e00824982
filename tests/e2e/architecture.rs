//! The crate graph holds the architecture's invariants (ARCHITECTURE.md): the compiler then
//! refuses parquet/arrow outside `dbbcal-io` and plotters outside `dbbcal-report`. These tests
//! hold the graph itself, transitively, from `Cargo.lock` (which lists every package's
//! dependencies, dev-dependencies included: a dev-dependency that pulled parquet into core's
//! tests would fail here too, as it would make core's tests link parquet). What the graph cannot
//! say, they read from the crates' own `Cargo.lock` entries and code: no file format in core or
//! dbbcal-machine, and one-way data flow inside core.

use std::collections::{BTreeMap, BTreeSet};

fn lock_graph() -> BTreeMap<String, Vec<String>> {
    let root = crate::support::root();
    let text = std::fs::read_to_string(root.join("Cargo.lock")).expect("Cargo.lock");
    let lock: toml::Value = toml::from_str(&text).expect("Cargo.lock is TOML");
    let mut graph = BTreeMap::new();
    for p in lock["package"].as_array().expect("[[package]]") {
        let name = p["name"].as_str().expect("name").to_string();
        let deps = p
            .get("dependencies")
            .and_then(|d| d.as_array())
            .map(|d| {
                d.iter()
                    // "name" or "name version" when two versions are locked.
                    .filter_map(|v| v.as_str()?.split(' ').next().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        graph
            .entry(name)
            .or_insert_with(Vec::new)
            .extend::<Vec<String>>(deps);
    }
    graph
}

/// Every package `from` depends on, directly or not (itself excluded).
fn closure(graph: &BTreeMap<String, Vec<String>>, from: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![from.to_string()];
    while let Some(p) = todo.pop() {
        for d in graph.get(&p).into_iter().flatten() {
            if seen.insert(d.clone()) {
                todo.push(d.clone());
            }
        }
    }
    seen
}

/// `krate`'s closure holds none of `forbidden`.
fn check(krate: &str, forbidden: &[&str]) {
    let graph = lock_graph();
    assert!(graph.contains_key(krate), "{krate} is not in Cargo.lock");
    let deps = closure(&graph, krate);
    let found: Vec<&&str> = forbidden.iter().filter(|f| deps.contains(**f)).collect();
    assert!(found.is_empty(), "{krate} depends on {found:?}");
}

#[test]
fn the_analysis_crate_links_neither_parquet_nor_plotters_nor_another_dbbcal_crate() {
    check(
        "dbbcal-core",
        &[
            "parquet",
            "arrow-array",
            "plotters",
            "dbbcal-io",
            "dbbcal-report",
            "dbbcal-sim",
            "dbbcal",
        ],
    );
}

#[test]
fn the_machine_kinds_crate_links_neither_parquet_nor_plotters_and_of_dbbcal_only_core() {
    // dbbcal-core for the kinds' format types (plain data); nothing that reads or draws.
    check(
        "dbbcal-machine",
        &[
            "parquet",
            "arrow-array",
            "plotters",
            "dbbcal-io",
            "dbbcal-report",
            "dbbcal-sim",
            "dbbcal",
        ],
    );
}

#[test]
fn only_the_io_crate_and_what_builds_on_it_link_parquet() {
    check(
        "dbbcal-report",
        &["parquet", "arrow-array", "dbbcal-core", "dbbcal-io"],
    );
    check(
        "dbbcal-testkit",
        &["parquet", "arrow-array", "plotters", "dbbcal-core"],
    );
    check("dbbcal-io", &["plotters", "dbbcal-report", "dbbcal-sim"]);
    check("dbbcal-sim", &["plotters", "dbbcal-report"]);
    check(
        "dbbcal-supervise",
        &[
            "parquet",
            "arrow-array",
            "plotters",
            "dbbcal-core",
            "dbbcal-io",
            "dbbcal-report",
        ],
    );
    let graph = lock_graph();
    assert!(
        closure(&graph, "dbbcal-io").contains("parquet"),
        "the io crate reads parquet"
    );
    assert!(
        closure(&graph, "dbbcal-report").contains("plotters"),
        "the report crate draws"
    );
}

/// The code of `path` (relative to the workspace root: an `.rs` file, or a folder and every `.rs`
/// file under it), by file and line: each line without its comment, and lines that are only a
/// comment (`//`, `///`, `//!`) left out. Comments may name what the code must not use, in prose
/// (`crates/core/src/lib.rs` says core has no serde); the crates use no `/* */` comments.
fn code_lines(path: &str) -> Vec<(String, String)> {
    fn walk(dir: &std::path::Path, files: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("a source folder") {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                walk(&path, files);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    let root = crate::support::root();
    let mut files = Vec::new();
    if root.join(path).is_file() {
        files.push(root.join(path));
    } else {
        walk(&root.join(path), &mut files);
    }
    files.sort();
    assert!(!files.is_empty(), "no .rs file at {path}");
    let mut lines = Vec::new();
    for file in files {
        let name = file
            .strip_prefix(&root)
            .unwrap_or(&file)
            .display()
            .to_string();
        let text = std::fs::read_to_string(&file).expect("a source file");
        for (i, line) in text.lines().enumerate() {
            let code = line.split_once("//").map_or(line, |(code, _)| code);
            if !code.trim().is_empty() {
                lines.push((format!("{name}:{}", i + 1), code.to_string()));
            }
        }
    }
    lines
}

/// Core and the machine kinds' crate know no file format (ARCHITECTURE.md, Invariants):
/// `campaign.toml`'s is `dbbcal_io::manifest`'s and every output record the application's. The
/// closure checks above cannot hold this: serde is in core's closure through its numeric
/// dependencies (argmin, chrono). So this looks at each crate's own dependencies, its
/// `[[package]]` entry in `Cargo.lock` (every table of its manifest: normal, dev, build, per
/// target; a renamed dependency under its package's name), and at its code: no line of its
/// `src/` outside a comment names `Serialize`, `Deserialize` or `serde::` (a comment may, in
/// prose).
#[test]
fn the_analysis_crates_know_no_file_format_by_dependency_or_by_derive() {
    let graph = lock_graph();
    let forbidden = [
        "serde",
        "serde_derive",
        "serde_json",
        "toml",
        "csv",
        "anyhow",
        "clap",
        "parquet",
        "arrow-array",
        "plotters",
    ];
    for (krate, src) in [
        ("dbbcal-core", "crates/core/src"),
        ("dbbcal-machine", "crates/machine/src"),
    ] {
        let own = graph
            .get(krate)
            .unwrap_or_else(|| panic!("{krate} is not in Cargo.lock"));
        let deps: Vec<&str> = forbidden
            .into_iter()
            .filter(|f| own.iter().any(|d| d == f))
            .collect();
        let code: Vec<String> = code_lines(src)
            .into_iter()
            .filter(|(_, code)| {
                ["Serialize", "Deserialize", "serde::"]
                    .iter()
                    .any(|w| code.contains(w))
            })
            .map(|(at, code)| format!("{at}: {}", code.trim()))
            .collect();
        assert!(
            deps.is_empty() && code.is_empty(),
            "{krate} knows a file format: its own dependencies {deps:?}; code:\n{}",
            code.join("\n")
        );
    }
}

/// Inside core data flow one way, `signal` ← `series` ← `model` (ARCHITECTURE.md, Invariants):
/// `signal` uses no other module of the crate, and `series` none of the analysis built on it.
#[test]
fn inside_the_analysis_crate_signal_and_series_use_nothing_built_on_them() {
    let found = |paths: &[&str], uses: &dyn Fn(&str) -> bool| -> Vec<String> {
        paths
            .iter()
            .flat_map(|p| code_lines(p))
            .filter(|(_, code)| uses(code))
            .map(|(at, code)| format!("{at}: {}", code.trim()))
            .collect()
    };
    let signal = found(&["crates/core/src/signal"], &|code| {
        code.contains("super::super")
            || code
                .split("crate::")
                .skip(1)
                .any(|p| !p.starts_with("signal"))
    });
    assert!(
        signal.is_empty(),
        "signal uses the crate:\n{}",
        signal.join("\n")
    );
    let above_series = [
        "model",
        "fit",
        "identify",
        "diagnose",
        "matching",
        "calibrate",
        "compensate",
        "acceptance",
    ];
    let series = found(
        &["crates/core/src/series.rs", "crates/core/src/series"],
        &|code| {
            above_series.iter().any(|m| {
                code.contains(&format!("crate::{m}")) || code.contains(&format!("super::{m}"))
            })
        },
    );
    assert!(
        series.is_empty(),
        "series uses the analysis built on it:\n{}",
        series.join("\n")
    );
}

/// Each package's features as `cargo tree` resolves them for `selection` (offline, locked).
fn resolved_features(selection: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .current_dir(crate::support::root())
        .args(["tree", "--offline", "--locked", "--prefix", "none"])
        .args(["-e", "normal,build,dev", "-f", "{p}|{f}"])
        .args(selection)
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut features: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let line = line.trim_end_matches(" (*)");
        if let Some((package, list)) = line.split_once('|') {
            let set = features.entry(package.to_string()).or_default();
            set.extend(
                list.split(',')
                    .filter(|f| !f.is_empty())
                    .map(str::to_string),
            );
        }
    }
    features
}

/// `cargo test -p dbbcal-io` or `-p dbbcal-sim` resolves every package they share with the
/// workspace with the workspace's features (the pins in `crates/io/Cargo.toml`): otherwise
/// each such selection builds parquet/arrow a second time.
#[test]
fn testing_one_member_reuses_the_workspaces_build_of_its_dependencies() {
    let workspace = resolved_features(&["--workspace"]);
    for member in ["dbbcal-io", "dbbcal-sim"] {
        let alone = resolved_features(&["-p", member]);
        let differ: Vec<&String> = alone
            .iter()
            .filter(|(p, f)| workspace.get(*p).is_some_and(|w| w != *f))
            .map(|(p, _)| p)
            .collect();
        assert!(
            differ.is_empty(),
            "-p {member} resolves other features for {differ:?}"
        );
        assert!(
            alone.keys().any(|p| p.starts_with("parquet ")),
            "{member} builds on parquet"
        );
    }
}
