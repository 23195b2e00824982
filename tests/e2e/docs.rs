//! The tables users read are the definitions the code uses: the README's exit codes
//! (`dbbcal::exit`), `docs/guarantees.md`'s limits (`pipeline::limits_table`,
//! `campaign::limits_table`, made from the constants the checks use). A table changed on one
//! side only fails here.

fn doc(path: &str) -> String {
    std::fs::read_to_string(crate::support::root().join(path)).unwrap()
}

/// `text` holds `table` word for word; else the table it should hold is printed.
fn check(file: &str, what: &str, table: &str) {
    assert!(
        doc(file).contains(table),
        "{file}: the {what} table is not the code's; it should read:\n{table}"
    );
}

#[test]
fn the_readme_and_help_list_the_exit_codes_main_uses() {
    check("README.md", "exit-code", &dbbcal::exit::markdown_table());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_dbbcal"))
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.contains(dbbcal::exit::help_text().trim_end()),
        "{help}"
    );
}

#[test]
fn the_guarantees_list_the_limits_the_checks_use() {
    check(
        "docs/guarantees.md",
        "pipeline limits",
        &dbbcal::pipeline::limits_table(),
    );
    check(
        "docs/guarantees.md",
        "manifest limits",
        &dbbcal::campaign::limits_table(),
    );
}
