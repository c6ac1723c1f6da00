//! Any bytes as a recordings CSV: an error naming the file, or recordings whose every value is
//! finite with strictly increasing times. Never a panic, a hang or a runaway allocation.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = rtr::io::utf8_text(bytes.to_vec(), "fuzz.csv") else {
        return;
    };
    match rtr::data::Recordings::parse("fuzz.csv", &text) {
        Ok(recordings) => {
            for track in &recordings.tracks {
                assert!(track.len() >= 2);
                assert!(track.t.windows(2).all(|w| w[1] > w[0]));
                for column in [&track.x, &track.y, &track.heading, &track.speed] {
                    assert!(column.iter().all(|v| v.is_finite()));
                }
            }
        }
        Err(e) => assert!(e.to_string().contains("fuzz.csv"), "{e}"),
    }
});
