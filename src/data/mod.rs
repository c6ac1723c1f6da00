//! Real driving logs: loaders, tracks, the shipped A9 dataset, and the cutting of recordings
//! into scenes.

pub mod a9;
pub mod automatum;
pub mod bend;
pub mod closing_events;
pub mod commonroad;
pub mod logged_infractions;
pub mod motion;
pub mod recordings;
mod repeated_tracks;
pub mod scene_list;
pub mod summary;
pub mod track;
pub mod traffic;
pub mod windows;

pub use a9::A9Dataset;
pub use automatum::{A9_DYNAMIC_SHA256, A9_STATIC_SHA256, Recording, load_recording, sha256_file};
pub use bend::bend_scenes;
pub use closing_events::{ClosingEvents, closing_events};
pub use logged_infractions::{LoggedInfractions, logged_infractions};
pub use recordings::{RecordedTrack, Recordings};
pub use scene_list::{read_scene_list, write_scene_list};
pub use summary::{DataSummary, summarize};
pub use track::{AgentState, Track, TrackSample, VehicleClass};
pub use traffic::{LaneTraffic, TrafficStatistics, VehicleSample, rank_from_right};
pub use windows::{SceneConfig, SceneSplit, build_all_scenes, build_scenes};
