//! Any bytes as an OpenDRIVE file: an error naming the file, or a map whose lanes are finite,
//! 0-10 m wide, with a positive speed limit. Never a panic, a hang or a runaway allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = rtr::io::utf8_text(bytes.to_vec(), "fuzz.xodr") else {
        return;
    };
    match rtr::map::Map::from_xodr_str(&text, "fuzz.xodr") {
        Ok(map) => {
            for lane in map.lanes() {
                assert!(lane.centerline.iter().flatten().all(|v| v.is_finite()));
                assert!(lane.widths.iter().all(|w| (0.0..=10.0).contains(w)));
                assert!(lane.speed_limit > 0.0);
            }
        }
        Err(e) => assert!(e.to_string().contains("fuzz.xodr"), "{e}"),
    }
});
