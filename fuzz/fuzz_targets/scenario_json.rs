//! Any bytes as a concrete scenario (`rtr scenarios generate` JSON): an error naming the file,
//! or a scenario that survives its own round trip. Never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rtr::scenario::ConcreteScenario;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = rtr::io::utf8_text(bytes.to_vec(), "fuzz.json") else {
        return;
    };
    match ConcreteScenario::from_json_str(&text, "fuzz.json") {
        Ok(scenario) => {
            let again = scenario.to_json().expect("a loaded scenario encodes");
            ConcreteScenario::from_json_str(&again, "again.json").expect("and loads back");
        }
        Err(e) => assert!(e.to_string().contains("fuzz.json"), "{e}"),
    }
});
