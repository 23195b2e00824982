use super::*;

#[test]
fn resolve_removes_dots_beyond_the_existing_part() {
    let tmp = tempfile::tempdir().unwrap();
    let base = tmp.path().canonicalize().unwrap();
    std::fs::create_dir(base.join("c")).unwrap();
    let p = base.join("x/../c/y/./z/..");
    assert_eq!(resolve(&p).unwrap(), base.join("c/y"));
    assert_eq!(resolve(&base.join("c/..")).unwrap(), base);
}

#[test]
fn overlap_is_found_in_each_direction() {
    let tmp = tempfile::tempdir().unwrap();
    let c = tmp.path().canonicalize().unwrap().join("camp");
    std::fs::create_dir(&c).unwrap();
    let check = |out: &Path| {
        let name = out.file_name().unwrap().to_str().unwrap();
        check_overlap(out, out.parent().unwrap(), name, &c)
    };
    assert!(check(&c).is_err());
    assert!(check(&c.join("out")).is_err());
    assert!(check(c.parent().unwrap()).is_err());
    assert!(check(&c.with_file_name("camp-out")).is_ok());
    // Inside what a run may remove or replace: OUT.prev, a partial folder; by identity.
    assert!(check(&c.with_file_name("cam")).is_ok());
    let prev = c.with_file_name("x.prev");
    std::fs::create_dir(&prev).unwrap();
    std::os::unix::fs::symlink(&c, prev.join("link")).unwrap();
    assert!(
        check(&c.with_file_name("x")).is_ok(),
        "a link is not removed with its folder"
    );
    std::fs::write(c.join("a.parquet"), "x").unwrap();
    std::fs::hard_link(c.join("a.parquet"), prev.join("a.parquet")).unwrap();
    assert!(check(&c.with_file_name("x"))
        .unwrap_err()
        .to_string()
        .contains("a.parquet"));
    let camp2 = prev.join("c2");
    std::fs::create_dir(&camp2).unwrap();
    let name = "x";
    assert!(
        check_overlap(&c.with_file_name(name), c.parent().unwrap(), name, &camp2)
            .unwrap_err()
            .to_string()
            .contains("x.prev")
    );
}

#[test]
fn after_a_dead_run_its_partial_folders_and_lock_go_unless_another_run_holds_the_lock() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let marker = serde_json::to_string(&Marker::new(
        "c",
        Default::default(),
        Default::default(),
        Default::default(),
    ))
    .unwrap();
    let make = |held: bool| {
        std::fs::create_dir_all(d.join(".out.partial-123")).unwrap();
        std::fs::write(d.join(".out.partial-123").join(MARKER), &marker).unwrap();
        std::fs::create_dir_all(d.join(".out.partial-124")).unwrap();
        std::fs::create_dir_all(d.join(".out.partial-mine")).unwrap();
        std::fs::write(d.join(".out.partial-mine/x"), "x").unwrap();
        let lock = File::create(d.join(".out.lock")).unwrap();
        if held {
            lock.try_lock().unwrap();
        }
        lock
    };
    let names = || {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let other_run = make(true);
    assert!(!clean_up_after_dead_run(&d.join("out")).unwrap());
    assert_eq!(names().len(), 4, "{:?}", names());
    drop(other_run);
    let _file = make(false);
    assert!(clean_up_after_dead_run(&d.join("out")).unwrap());
    assert_eq!(names(), [".out.partial-mine"]);
    assert!(!clean_up_after_dead_run(&d.join("gone/out")).unwrap());
    assert!(!d.join("gone").exists());
}

#[test]
fn an_output_is_dbbcal_s_only_while_it_holds_nothing_its_marker_does_not_list() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().join("out");
    std::fs::create_dir_all(d.join("figures")).unwrap();
    let marker = |files: Option<Vec<String>>| {
        let m = Marker {
            files,
            ..Marker::new(
                "c",
                Default::default(),
                Default::default(),
                Default::default(),
            )
        };
        std::fs::write(d.join(MARKER), serde_json::to_string(&m).unwrap()).unwrap();
    };
    std::fs::write(d.join("summary.json"), "{}").unwrap();
    std::fs::write(d.join("figures/bar-B01.png"), "png").unwrap();
    // A marker of a version before the list: judged by the names dbbcal writes.
    marker(None);
    assert!(dbbcal_output(&d).is_ok());
    assert!(check_replaceable(&d, "").is_ok());
    std::fs::write(d.join("figures/signed.pdf"), "pdf").unwrap();
    assert!(dbbcal_output(&d)
        .unwrap_err()
        .to_string()
        .contains("figures/signed.pdf"));
    std::fs::remove_file(d.join("figures/signed.pdf")).unwrap();
    // With the list: exactly what it lists.
    let listed = vec![
        "figures/".into(),
        "figures/bar-B01.png".into(),
        "summary.json".into(),
    ];
    marker(Some(listed));
    assert!(dbbcal_output(&d).is_ok());
    std::fs::write(d.join("NOTES.txt"), "notes").unwrap();
    let why = check_replaceable(&d, "").unwrap_err().to_string();
    assert!(
        why.contains("NOTES.txt") && why.contains("did not write"),
        "{why}"
    );
    std::fs::remove_file(d.join("NOTES.txt")).unwrap();
    std::fs::create_dir(d.join("summary.json.d")).unwrap();
    assert!(dbbcal_output(&d).is_err(), "a folder it did not list");
}

#[test]
fn a_name_and_its_previous_outputs_share_one_lock() {
    let p = Path::new("/r");
    for name in ["out", "out.prev", "out.prev.prev"] {
        assert_eq!(lock_file(p, name), Path::new("/r/.out.lock"), "{name}");
    }
    assert_eq!(lock_file(p, ".prev"), Path::new("/r/..prev.lock"));
    assert_eq!(
        lock_file(p, "night.prevx"),
        Path::new("/r/.night.prevx.lock")
    );
}

#[test]
fn control_characters_are_escaped() {
    assert_eq!(escape("a\nb\u{1b}[31m"), "a\\nb\\u{1b}[31m");
    assert_eq!(escape("µm ok"), "µm ok");
}

#[test]
fn names_that_are_not_folders_are_refused() {
    for p in [".", "..", "/", "a/..", ""] {
        assert!(final_name(Path::new(p)).is_none(), "{p}");
    }
    assert_eq!(final_name(Path::new("a/b")).as_deref(), Some("b"));
}
