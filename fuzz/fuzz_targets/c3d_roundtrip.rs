//! A C3D file that reads, has points and a frame rate must survive `to_take -> set_take ->
//! write -> read` with the same take: identical validity, positions equal to within the
//! integer scale (or float precision), and the same number of analog samples.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_io::c3d::{self, Storage};

fuzz_target!(|data: &[u8]| {
    let Ok(file) = c3d::read(data) else { return };
    if file.point_count == 0 || file.frames == 0 {
        return;
    }
    let take = match file.to_take() {
        Ok(take) => take,
        // No valid frame rate: the file reads, but locap refuses to invent a time base.
        Err(locap_io::Error::Binary { section, offset: 20, .. }) if section == "header" => return,
        Err(e) => panic!("to_take of a file that read: {e}"),
    };
    let mut edited = file.clone();
    edited.set_take(&take).expect("set_take with the file's own take");
    let mut bytes = Vec::new();
    c3d::write(&edited, &mut bytes).expect("write of a file that read");
    let again = c3d::read(&bytes).expect("re-read of a written file");
    let take2 = again.to_take().expect("to_take of the re-read file");

    assert_eq!(take2.frame_count(), take.frame_count(), "frame count");
    assert_eq!(take2.marker_count(), take.marker_count(), "marker count");
    assert_eq!(take2.validity(), take.validity(), "validity mask");
    assert_eq!(again.analog.len(), file.analog.len(), "analog sample count");
    // One integer step of the written file, in mm (the file's unit may not be mm).
    let mm = file.point_unit().mm_per_unit();
    let step = match again.storage {
        Storage::Int => again.point_scale() as f64 * mm,
        Storage::Float => 0.0,
    };
    for f in 0..take.frame_count() {
        for k in 0..take.marker_count() {
            if let (Some(a), Some(b)) = (take.position_mm(f, k), take2.position_mm(f, k)) {
                for i in 0..3 {
                    // f32 storage: relative precision of a float, plus half an integer step.
                    let tol = 0.5 * step + a[i].abs().max(b[i].abs()) * 1e-6;
                    assert!(
                        (a[i] - b[i]).abs() <= tol,
                        "frame {f} marker {k} axis {i}: {} became {} (tolerance {tol})",
                        a[i],
                        b[i]
                    );
                }
            }
        }
    }
});
