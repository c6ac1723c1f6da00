//! Throughput of the data pipeline on the shipped A9 recording, printed as one JSON object:
//! `cargo bench --bench data_pipeline`.
//!
//! A plain harness (no criterion): each stage runs a few times and reports the best and the
//! median wall time, which is what matters for a pipeline run once per training job.

use std::time::Instant;

use rtr::data::{A9Dataset, SceneConfig, a9, logged_infractions};
use rtr::scene::SceneBatch;

fn time<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, f64, T) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..reps {
        let start = Instant::now();
        last = Some(f());
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (times[0], times[times.len() / 2], last.expect("reps > 0"))
}

fn main() {
    let dir = a9::default_dir();
    let (load_best, load_median, data) =
        time(3, || A9Dataset::load(&dir).expect("shipped data loads"));
    let config = SceneConfig::default();
    let (scenes_best, _, split) = time(3, || data.scenes(&config).expect("scenes"));
    let (infr_best, _, infractions) = time(3, || logged_infractions(&data.recording, &data.map));
    let device = rtr::backend::Backend::reference_device(false);
    let batch: Vec<_> = split.train.iter().take(32).collect();
    let (batch_best, _, _) = time(5, || {
        SceneBatch::from_scenes(&batch, &device).expect("batch")
    });
    let boxes = infractions.samples as f64;
    let report = serde_json::json!({
        "bench": "data_pipeline",
        "load_recording_and_map_s": {"best": load_best, "median": load_median},
        "build_scenes_s": scenes_best,
        "scenes": split.train.len() + split.test.len(),
        "logged_infractions_s": infr_best,
        "box_checks_per_s": boxes / infr_best,
        "scene_batch_32_s": batch_best,
    });
    rtr::outln!("{report}").expect("standard output");
}
