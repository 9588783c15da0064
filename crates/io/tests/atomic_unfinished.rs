//! `remove_unfinished` deletes every temporary being written in this process, so it is tested
//! alone in its own test binary: beside other tests it would remove their temporaries too.

use locap_io::atomic::{remove_unfinished, write_atomically};

#[test]
fn unfinished_temporaries_are_removed_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("take.txt");
    let err = write_atomically(&path, |w| {
        w.write_all(b"half")?;
        w.flush()?;
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "the temporary exists while writing");
        // What the program's signal handler does while a writer thread is busy.
        remove_unfinished();
        Ok(())
    });
    // The rename of the removed temporary fails, and nothing is left behind.
    assert!(err.is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    assert!(!path.exists());
}
