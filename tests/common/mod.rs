//! Shared fixtures for the integration tests: the shipped A9 dataset, loaded once per test
//! binary.

use std::sync::OnceLock;

use rtr::data::{A9Dataset, SceneConfig, SceneSplit, a9};

pub fn a9() -> &'static A9Dataset {
    static DATA: OnceLock<A9Dataset> = OnceLock::new();
    DATA.get_or_init(|| A9Dataset::load(&a9::default_dir()).expect("the shipped A9 data loads"))
}

#[allow(dead_code)] // not every test binary uses scenes
pub fn a9_scenes() -> &'static SceneSplit {
    static SCENES: OnceLock<SceneSplit> = OnceLock::new();
    SCENES.get_or_init(|| a9().scenes(&SceneConfig::default()).expect("scenes build"))
}
