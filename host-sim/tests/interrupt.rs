//! What a signal's handler removes (`host_sim::output::remove_staged`):
//! every temporary file a live `Outputs` staged and every directory it
//! made, none of the targets. Alone in its test binary: the registry is
//! the process's.

use host_sim::output::{remove_staged, Outputs};

#[test]
fn a_signal_leaves_no_staged_file_nor_made_directory_and_no_target_touched() {
    let dir = tempfile::tempdir().unwrap();
    let kept = dir.path().join("kept.txt");
    std::fs::write(&kept, "before\n").unwrap();
    let made = dir.path().join("new").join("deeper");
    let mut out = Outputs::new();
    out.create_dir(&made).unwrap();
    out.bytes(&kept, b"after\n").unwrap();
    out.bytes(&made.join("a.csv"), b"a\n").unwrap();
    let names = |d: &std::path::Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    // Staged: a temporary file beside each target.
    assert_eq!(names(dir.path()).len(), 3, "{:?}", names(dir.path()));
    assert_eq!(names(&made).len(), 1);
    let held = remove_staged();
    assert!(held.is_empty());
    drop(held);
    assert_eq!(names(dir.path()), ["kept.txt"]);
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "before\n");
    // The value dropped afterwards finds nothing left to remove.
    drop(out);
    assert_eq!(names(dir.path()), ["kept.txt"]);
    // A commit is not left half-done by it: a later value commits whole.
    let mut out = Outputs::new();
    out.bytes(&kept, b"after\n").unwrap();
    out.commit().unwrap();
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "after\n");
    assert!(remove_staged().is_empty());
}
