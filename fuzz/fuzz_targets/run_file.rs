//! Any bytes as a run file (`rtr train --config`): an error naming the file, or a config that
//! passes its own validation again after a round trip. Never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtr::train::TrainConfig;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = rtr::io::utf8_text(bytes.to_vec(), "fuzz.toml") else {
        return;
    };
    match TrainConfig::from_toml_str(&text, "fuzz.toml") {
        Ok(config) => {
            let again = toml::to_string(&config).expect("a loaded config encodes");
            TrainConfig::from_toml_str(&again, "again.toml").expect("and loads back");
        }
        Err(e) => assert!(e.to_string().contains("fuzz.toml"), "{e}"),
    }
});
