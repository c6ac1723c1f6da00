//! The curated scenario set: a scene list of A9 training scenes becomes the alpha share of a
//! run's initial states (with their logs, so imitation applies), and bad lists are refused
//! with the file and the scene named.

mod common;

use std::path::PathBuf;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rtr::data::write_scene_list;
use rtr::train::TrainConfig;
use rtr::train::config::DataConfig;
use rtr::train::sources::{InitialState, TrainingData};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtr-curated-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

#[test]
fn curated_scenes_are_the_alpha_share() {
    let dir = temp_dir("share");
    let split = common::a9_scenes();
    let ids: Vec<String> = [5, 77, 300]
        .iter()
        .map(|&k| split.train[k].id.clone())
        .collect();
    let list = dir.join("curated.txt");
    write_scene_list(&list, "test list", &ids).expect("write");
    let config = DataConfig {
        curated: Some(list),
        ..DataConfig::default()
    };
    let data = TrainingData::load(common::a9(), &config, true).expect("loads");
    assert!(
        data.longtail.is_empty(),
        "curated scenes replace the long-tail set"
    );
    assert_eq!(data.curated, vec![5, 77, 300]);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let curated = |states: &[InitialState]| {
        states
            .iter()
            .filter(|s| matches!(s, InitialState::Nominal(i) if data.curated.contains(i)))
            .count()
    };
    let all = data.sample(&mut rng, 400, 1.0);
    assert_eq!(curated(&all), 400);
    let half = data.sample(&mut rng, 2000, 0.5);
    let share = curated(&half) as f64 / 2000.0;
    assert!((0.45..0.55).contains(&share), "curated share {share}");
    // They are logged scenes: the trainer batches them as nominal (imitation applies).
    assert!(data.parts(&all).iter().all(|p| p.is_nominal()));
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn a_scene_that_is_not_a_training_scene_is_named() {
    let dir = temp_dir("unknown");
    let list = dir.join("curated.txt");
    let test_scene = common::a9_scenes().test[0].id.clone();
    write_scene_list(&list, "a test scene", std::slice::from_ref(&test_scene)).expect("write");
    let config = DataConfig {
        curated: Some(list.clone()),
        ..DataConfig::default()
    };
    let e = TrainingData::load(common::a9(), &config, true)
        .err()
        .expect("a test-split scene is refused")
        .to_string();
    assert!(
        e.contains(&list.display().to_string()) && e.contains(&test_scene),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn the_list_path_is_relative_to_the_run_file_and_excludes_a_longtail_folder() {
    let dir = temp_dir("config");
    let run = dir.join("run.toml");
    std::fs::write(
        &run,
        "method = \"RTR\"\nalpha = 0.5\n[data]\ncurated = \"list.txt\"\n",
    )
    .expect("write");
    let config = TrainConfig::from_toml_file(&run).expect("valid");
    assert_eq!(config.data.curated, Some(dir.join("list.txt")));
    std::fs::write(
        &run,
        "method = \"RTR\"\nalpha = 0.5\n[data]\ncurated = \"list.txt\"\nlongtail_dir = \"x\"\n",
    )
    .expect("write");
    let e = TrainConfig::from_toml_file(&run)
        .expect_err("both refused")
        .to_string();
    assert!(
        e.contains("data.curated") && e.contains("longtail_dir"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).expect("cleanup");
}
