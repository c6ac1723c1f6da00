//! The nominal dataset shipped with rtr: the AUTOMATUM A9 highway recording
//! (hw-a9-stammhamm-015) and its OpenDRIVE map, in `data/automatum-a9/` (see its NOTICE).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::automatum::{
    A9_DYNAMIC_SHA256, A9_STATIC_SHA256, Recording, load_recording, sha256_file,
};
use super::windows::{SceneConfig, SceneSplit, build_scenes};
use crate::error::{Error, Result};
use crate::map::{LaneGraph, Map};

pub const DYNAMIC_FILE: &str = "dynamicWorld.v3_0-4-4.json.gz";
pub const STATIC_FILE: &str = "staticWorld.xodr";
/// The paper's lane-graph node spacing (m).
pub const LANE_NODE_LENGTH: f64 = 10.0;

/// Where the shipped copy lives in this source tree.
pub fn default_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/automatum-a9")
}

/// The recording, its map and the map's lane graph.
#[derive(Debug, Clone)]
pub struct A9Dataset {
    pub recording: Recording,
    pub map: Arc<Map>,
    pub lane_graph: Arc<LaneGraph>,
}

/// The A9 map alone (for the benches), checked against its published sha256 like
/// [`A9Dataset::load`] does.
pub fn load_map(dir: &Path) -> Result<Map> {
    let xodr = dir.join(STATIC_FILE);
    let actual = sha256_file(&xodr)?;
    if actual != A9_STATIC_SHA256 {
        return Err(Error::Checksum {
            path: xodr,
            expected: A9_STATIC_SHA256.into(),
            actual,
        });
    }
    Map::from_xodr_file(&xodr)
}

impl A9Dataset {
    /// Loads both files from `dir`, checking each against its published sha256.
    pub fn load(dir: &Path) -> Result<Self> {
        let map = Arc::new(load_map(dir)?);
        let lane_graph = Arc::new(LaneGraph::build(&map, LANE_NODE_LENGTH));
        let recording = load_recording(&dir.join(DYNAMIC_FILE), Some(A9_DYNAMIC_SHA256))?;
        Ok(Self {
            recording,
            map,
            lane_graph,
        })
    }

    /// Cuts the recording into train and test scenes.
    pub fn scenes(&self, config: &SceneConfig) -> Result<SceneSplit> {
        build_scenes(
            &self.recording,
            "a9",
            self.map.clone(),
            self.lane_graph.clone(),
            config,
        )
    }
}
