//! Training: every method on a tiny config lowers its loss, a killed and resumed run equals an
//! uninterrupted one, divergence stops cleanly, two devices compute the one-device step, and
//! bad run files are named. (PPO's ratio and GAE arithmetic, early termination and clipping
//! are unit tests beside the code in `src/train/`; BPTT against finite differences is in
//! `tests/gradients.rs`.)

mod common;

use std::path::Path;
use std::sync::OnceLock;

use burn::module::Module;
use indicatif::ProgressBar;
use rtr::train::session::devices;
use rtr::train::{CurveRow, DataConfig, TrainConfig, Trainer, TrainingData};

/// One nominal scene (so every minibatch holds the same initial states) and three long-tail
/// scenarios, shared by every test of this binary.
fn data() -> &'static TrainingData {
    static DATA: OnceLock<TrainingData> = OnceLock::new();
    DATA.get_or_init(|| {
        let config = DataConfig {
            nominal_limit: Some(1),
            longtail_generate: 26,
            longtail_limit: Some(3),
            ..DataConfig::default()
        };
        TrainingData::load(common::a9(), &config, true).expect("training data")
    })
}

/// A tiny run of `method`; `extra` is appended TOML (top-level keys first).
fn tiny(method: &str, top: &str, sections: &str) -> TrainConfig {
    let text = format!(
        r#"
method = "{method}"
seed = 11
{top}

[optimizer]
learning_rate = 1e-3
epochs = 1
epoch_scenes = 2

[ppo]
batch = 2
minibatch = 2

[imitation]
minibatch = 2

[data]
max_rollout_steps = 4

[model]
hidden = 16
lane_layers = 1
interaction_rounds = 1
history_blocks = 1
head_hidden = [16]
{sections}
"#
    );
    TrainConfig::from_toml_str(&text, "tiny.toml").expect("tiny config")
}

fn train(
    config: TrainConfig,
    dir: &Path,
    resume: bool,
    stop_after: Option<usize>,
) -> Vec<CurveRow> {
    let devices = devices(&config).expect("devices");
    let mut trainer = Trainer::new(config, data(), devices, dir, resume).expect("trainer");
    trainer
        .run(&ProgressBar::hidden(), stop_after)
        .expect("training runs");
    trainer.curves().to_vec()
}

/// Trains `method` on the same initial states three times and checks the loss fell.
fn loss_falls(method: &str, top: &str, sections: &str) {
    loss_falls_with(method, top, sections, |_| {});
}

fn loss_falls_with(method: &str, top: &str, sections: &str, edit: impl Fn(&mut TrainConfig)) {
    let dir = tempfile::tempdir().expect("temp dir");
    // BC and IL take one step per iteration; PPO methods three passes over one collection.
    let mut config = if matches!(method, "BC" | "IL") {
        let mut c = tiny(method, top, sections);
        c.optimizer.epochs = 3;
        c
    } else {
        let mut c = tiny(method, top, sections);
        c.ppo.epochs = 3;
        c
    };
    edit(&mut config);
    let rows = train(config, dir.path(), false, None);
    assert_eq!(rows.len(), 3, "{method}: three optimizer steps");
    let (first, last) = (rows[0].loss, rows[2].loss);
    assert!(
        last < first,
        "{method}: loss {first} -> {} -> {last} did not fall",
        rows[1].loss
    );
}

/// Writes a dynamics file of one acceleration lag of `tau` seconds.
fn write_lag(path: &Path, tau: f64) {
    let text = format!("[[terms]]\neffect = \"accel_lag\"\nparams = {{ tau_s = {tau} }}\n");
    std::fs::write(path, text).expect("dynamics file written");
}

#[test]
fn a_resume_after_an_input_file_changed_is_refused_naming_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let dynamics = dir.path().join("dynamics.toml");
    write_lag(&dynamics, 0.4);
    let mut config = tiny("IL", "", "");
    config.optimizer.epochs = 3;
    config.dynamics = Some(dynamics.clone());
    let run = dir.path().join("run");
    train(config.clone(), &run, false, Some(1));
    write_lag(&dynamics, 0.6);
    let devices = devices(&config).expect("devices");
    let err = Trainer::new(config.clone(), data(), devices, &run, true)
        .err()
        .expect("a run whose physics changed mid-run is refused");
    let message = err.to_string();
    assert!(
        message.contains("dynamics") && message.contains("other contents"),
        "{message}"
    );
    // The run kept the file it read: the message's own command puts it back.
    restore_as_told(&message);
    let rows = train(config, &run, true, None);
    assert_eq!(rows.len(), 3, "restored, the run resumes");
}

/// Runs the "`cp KEPT PATH` restores it" of `message`.
fn restore_as_told(message: &str) {
    let command = message
        .split("`cp ")
        .nth(1)
        .and_then(|rest| rest.split('`').next())
        .unwrap_or_else(|| panic!("no restore command in: {message}"));
    let (kept, path) = command.split_once(' ').expect("two paths");
    std::fs::copy(kept, path).expect("restored");
}

#[test]
fn evaluating_a_run_refuses_a_config_or_dynamics_file_changed_since_it_trained() {
    let dir = tempfile::tempdir().expect("temp dir");
    let dynamics = dir.path().join("dynamics.toml");
    write_lag(&dynamics, 0.4);
    let mut config = tiny("IL", "", "");
    config.dynamics = Some(dynamics.clone());
    let run = dir.path().join("run");
    train(config, &run, false, None);
    let device = rtr::backend::Backend::reference_device(false);
    let load = |path: &Path| rtr::eval::TrainedPolicy::load(path, &device).map(|_| ());
    let newest = run.join("checkpoints/iter-000001");
    for target in [run.as_path(), newest.as_path()] {
        load(target).expect("the run as trained loads");
    }

    write_lag(&dynamics, 0.6);
    for target in [run.as_path(), newest.as_path()] {
        let message = load(target).expect_err("other physics").to_string();
        assert!(
            message.contains("dynamics.toml") && message.contains("other contents"),
            "{message}"
        );
    }
    restore_as_told(&load(&run).expect_err("other physics").to_string());
    load(&run).expect("restored from the run's own copy");
    // A hand-edited digest too short to abbreviate is named whole, not a panic.
    let state = newest.join("state.json");
    let text = std::fs::read_to_string(&state).expect("state.json");
    let digest = text
        .split('"')
        .skip_while(|part| !part.starts_with("dynamics "))
        .nth(2)
        .expect("the dynamics digest")
        .to_string();
    std::fs::write(&state, text.replace(&digest, "abc")).expect("edited");
    let message = load(&newest).expect_err("another digest").to_string();
    assert!(message.contains("abc then"), "{message}");
    std::fs::write(&state, text).expect("restored");

    let config_toml = run.join("config.toml");
    let text = std::fs::read_to_string(&config_toml).expect("config.toml");
    let edited = text.replace("seed = 11", "seed = 12");
    assert_ne!(edited, text, "the run's config.toml names its seed");
    std::fs::write(&config_toml, edited).expect("edited");
    for target in [run.as_path(), newest.as_path()] {
        let message = load(target).expect_err("another config").to_string();
        assert!(
            message.contains("config.toml") && message.contains("seed"),
            "{message}"
        );
    }
}

#[test]
fn a_kept_run_is_checked_against_the_config_that_would_train_it_now() {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = tiny("IL", "", "");
    train(config.clone(), dir.path(), false, None);
    rtr::train::identity::check_same_run(dir.path(), &config).expect("the same run");
    let mut other = config.clone();
    other.optimizer.learning_rate *= 2.0;
    let err = rtr::train::identity::check_same_run(dir.path(), &other).expect_err("another base");
    assert!(err.to_string().contains("another config"), "{err}");
}

#[test]
fn bc_lowers_its_loss() {
    loss_falls("BC", "", "");
}

#[test]
fn il_lowers_its_loss() {
    loss_falls("IL", "", "");
}

#[test]
fn il_in_identified_dynamics_trains_and_the_physics_is_in_its_rollouts() {
    // A dynamics file as `rtr sim2real` writes it: the terms keep memory
    // channels through the training rollout and its gradients.
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("dynamics.toml");
    std::fs::write(
        &path,
        "[[terms]]\neffect = \"dead_time\"\nparams = { delay_s = 0.6 }\n\n\
         [[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 0.8 }\n",
    )
    .expect("written");
    loss_falls_with("IL", "", "", |c| c.dynamics = Some(path.clone()));
    let plain = train(tiny("IL", "", ""), &dir.path().join("plain"), false, None);
    let mut config = tiny("IL", "", "");
    config.dynamics = Some(path.clone());
    let lagged = train(config, &dir.path().join("lagged"), false, None);
    assert_ne!(
        plain[0].il_loss, lagged[0].il_loss,
        "the terms change the rollout"
    );
}

/// Perturbed starts turn and shift each controlled agent's history rigidly, within the
/// configured bounds, and leave its logged future (the imitation target) and every other agent
/// as recorded; the same draw gives the same scene.
#[test]
fn start_perturbation_moves_only_controlled_histories_rigidly() {
    use rtr::scene::AgentRole;
    use rtr::train::perturbation::StartPerturbation;
    let scene = &data().nominal[0];
    let p = StartPerturbation {
        lateral_m: 0.5,
        heading_rad: 0.02,
    };
    let out = p.apply(&[scene], &[3], 11, 7).remove(0);
    assert_eq!(
        out.agents,
        p.apply(&[scene], &[3], 11, 7)[0].agents,
        "same draw"
    );
    assert_ne!(
        out.agents,
        p.apply(&[scene], &[4], 11, 7)[0].agents,
        "another slot"
    );
    let now = scene.current_step();
    let mut moved = 0;
    for (before, after) in scene.agents.iter().zip(&out.agents) {
        assert_eq!(
            before.states[now + 1..],
            after.states[now + 1..],
            "future kept"
        );
        if before.role != AgentRole::Controlled {
            assert_eq!(before, after, "only controlled agents move");
            continue;
        }
        let (b, a) = (before.states[now], after.states[now]);
        let turn = a.heading - b.heading;
        assert!(turn.abs() <= 0.02 + 1e-12, "turn {turn}");
        let shift = (a.x - b.x).hypot(a.y - b.y);
        assert!(shift <= 0.5 + 1e-9, "shift {shift}");
        moved += usize::from(shift > 1e-6);
        for k in 0..now {
            if !before.valid[k] {
                continue;
            }
            let d = |s: &[rtr::data::AgentState]| (s[k].x - s[now].x).hypot(s[k].y - s[now].y);
            assert!((d(&before.states) - d(&after.states)).abs() < 1e-9, "rigid");
            assert!((after.states[k].heading - before.states[k].heading - turn).abs() < 1e-12);
            assert_eq!(after.states[k].speed, before.states[k].speed);
        }
    }
    assert!(moved > 0, "some agent moved");
}

/// The imitation rollout starts from the perturbed states (IL and RTR): before any step, the
/// imitation loss of the same initial state is higher when its start is off the logged path.
#[test]
fn imitation_rollouts_start_from_the_perturbed_states() {
    for method in ["IL", "RTR"] {
        let first_il = |perturb: bool| {
            let dir = tempfile::tempdir().expect("temp dir");
            let mut config = tiny(method, "", "");
            config.alpha = 0.0;
            config.run.max_iterations = Some(1);
            config.ppo.value_warmup_iterations = 0;
            if perturb {
                config.imitation.perturbation = Some(rtr::train::perturbation::StartPerturbation {
                    lateral_m: 1.0,
                    heading_rad: 0.05,
                });
            }
            train(config, dir.path(), false, None)[0].il_loss
        };
        let (plain, perturbed) = (first_il(false), first_il(true));
        assert!(
            perturbed > plain && plain > 0.0,
            "{method}: IL loss {plain} from the logs, {perturbed} from perturbed starts"
        );
    }
}

/// Agent dropout removes agents at its rate, keeps the rest as recorded and in order, always
/// leaves a controlled agent, and draws the same agents for the same slot and iteration.
#[test]
fn agent_dropout_removes_agents_at_its_rate_and_keeps_a_controlled_one() {
    use rtr::scene::{AgentRole, Scene};
    use rtr::train::agent_dropout::drop_agents;
    let scene = &data().nominal[0];
    let n = scene.agents.len();
    assert!(n >= 3, "the test scene has {n} agents");
    let controlled = |s: &Scene| {
        s.agents
            .iter()
            .filter(|a| a.role == AgentRole::Controlled)
            .count()
    };
    assert!(
        controlled(scene) >= 2,
        "the test scene needs two controlled agents"
    );
    let kept_all = drop_agents(&[scene], &[0], 0.0, 11, 0).remove(0);
    assert_eq!(kept_all.agents, scene.agents, "rate 0 keeps every agent");
    let draws = 400;
    let (mut removed, mut lone) = (0, 0);
    for iteration in 0..draws {
        for rate in [0.5, 0.95] {
            let out = drop_agents(&[scene], &[3], rate, 11, iteration).remove(0);
            let again = drop_agents(&[scene], &[3], rate, 11, iteration).remove(0);
            assert_eq!(out.agents, again.agents, "same draw");
            let mut recorded = scene.agents.iter();
            for agent in &out.agents {
                assert!(
                    recorded.any(|a| a == agent),
                    "kept as recorded and in order"
                );
            }
            assert!(controlled(&out) >= 1, "a controlled agent stays");
            if rate == 0.5 {
                removed += n - out.agents.len();
            } else {
                lone += usize::from(out.agents.len() == 1);
            }
        }
    }
    // Binomial: the removed share's standard deviation is at most 0.5 / sqrt(n draws) = 0.0125
    // here; the kept controlled agent lowers the mean by at most 0.5^2 / n.
    let share = removed as f64 / (n * draws) as f64;
    assert!(
        (share - 0.5).abs() < 0.07,
        "removed share {share} at rate 0.5"
    );
    assert!(
        lone > draws / 2,
        "at rate 0.95 most draws leave one agent: {lone} of {draws}"
    );
    let other_slot = (0..draws)
        .filter(|&i| {
            drop_agents(&[scene], &[3], 0.5, 11, i)[0].agents
                != drop_agents(&[scene], &[4], 0.5, 11, i)[0].agents
        })
        .count();
    assert!(other_slot > 0, "another slot draws other agents");
}

/// The imitation rollout starts from the scenes with agents dropped (IL and RTR): the first
/// imitation loss of the same initial state changes.
#[test]
fn imitation_rollouts_run_on_the_scenes_with_agents_dropped() {
    for method in ["IL", "RTR"] {
        let first_il = |dropout: f64| {
            let dir = tempfile::tempdir().expect("temp dir");
            let mut config = tiny(method, "", "");
            config.alpha = 0.0;
            config.run.max_iterations = Some(1);
            config.ppo.value_warmup_iterations = 0;
            config.imitation.agent_dropout = dropout;
            train(config, dir.path(), false, None)[0].il_loss
        };
        let (all, dropped) = (first_il(0.0), first_il(0.9));
        assert!(
            all > 0.0 && dropped > 0.0 && (all - dropped).abs() > 1e-6 * all,
            "{method}: IL loss {all} with every agent, {dropped} with agents dropped"
        );
    }
}

#[test]
fn rl_lowers_its_loss() {
    loss_falls("RL", "alpha = 0.5", "");
}

#[test]
fn rl_shaped_lowers_its_loss() {
    loss_falls("RL-Shaped", "alpha = 0.5", "");
}

#[test]
fn bc_plus_rl_lowers_its_loss() {
    loss_falls("BC+RL", "", "");
}

#[test]
fn rtr_lowers_its_loss() {
    loss_falls("RTR", "alpha = 0.5", "");
}

#[test]
fn rtr_scene_level_ppo_lowers_its_loss() {
    loss_falls_with("RTR", "alpha = 0.5", "", |c| {
        c.ppo.variant = rtr::train::PpoVariant::SceneLevel
    });
}

/// A frozen policy of the tiny config (another initialisation than the trained one), the same
/// in every test: drawn and saved under the trainer's lock on the device RNG, so tests running
/// in parallel cannot interleave their draws with it.
fn reference_policy(dir: &Path) -> String {
    saved_policy(dir, "reference.bpk", 99)
}

/// A tiny policy drawn with `seed`, saved as `dir/name`.
fn saved_policy(dir: &Path, name: &str, seed: u64) -> String {
    let config = tiny("IL", "", "");
    let device = rtr::backend::Backend::reference_device(false);
    let path = dir.join(name);
    rtr::seeding::with_seeded_device(&device, seed, || {
        rtr::model::PolicyNetwork::new(&config.model, &device).save_file(&path)
    })
    .expect("save reference");
    path.display().to_string()
}

#[test]
fn kl_loss_and_kl_reward_lower_their_loss() {
    let dir = tempfile::tempdir().expect("temp dir");
    let reference = reference_policy(dir.path());
    let section = format!("[reference]\ncheckpoint = \"{reference}\"\nweight = 1.0");
    loss_falls("KL-L", "alpha = 0.5", &section);
    loss_falls("KL-R", "alpha = 0.5", &section);
}

/// KL-L warm-started from its own reference: with the reference's sigma measured on the logs
/// as the warm start's is, the first KL is zero; with the reference's own (never trained) sigma
/// it is not, though both have the same mean.
#[test]
fn a_reference_with_sigma_from_the_logs_starts_at_zero_kl() {
    let dir = tempfile::tempdir().expect("temp dir");
    let reference = reference_policy(dir.path());
    let first_kl = |calibrated: bool, out: &str| {
        let section = format!(
            "[reference]\ncheckpoint = \"{reference}\"\nweight = 1.0\nstd_from_logs = {calibrated}"
        );
        let mut config = tiny("KL-L", "alpha = 0.5", &section);
        config.init = Some(rtr::train::InitConfig {
            policy: reference.clone().into(),
            std_from_logs: true,
            std_scale: [1.0, 1.0],
            add_agent_edge_motion: false,
            agent_edge_motion_scale: 1.0,
        });
        config.ppo.value_warmup_iterations = 0;
        let rows = train(config, &dir.path().join(out), false, Some(1));
        rows[0].kl
    };
    let calibrated = first_kl(true, "calibrated");
    assert!(calibrated.abs() < 1e-6, "{calibrated}");
    let raw = first_kl(false, "raw");
    assert!(raw > 0.1, "{raw}");
}

/// KL-L with the warm start itself as reference (`[reference] init = true`), warm-started as
/// the main PPO stage is (relative-motion inputs added, sigma from the logs x 2.32): the first
/// KL is zero, the KL grows as the policy moves, and a killed run resumes to the uninterrupted
/// run's curves, so the reference is rebuilt the same.
#[test]
fn the_warm_start_as_reference_starts_at_zero_kl_and_resumes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let warm = reference_policy(dir.path());
    // Added motion weights at zero (the run files' choice) and drawn (scale 1): the reference
    // must draw the same ones.
    for scale in [0.0, 1.0] {
        // The first line goes into tiny's [model] section.
        let sections = format!(
            "agent_edge_motion = true\n[init]\npolicy = \"{warm}\"\nstd_from_logs = true\n\
             std_scale = [2.32, 1.0]\nadd_agent_edge_motion = true\n\
             agent_edge_motion_scale = {scale:?}\n[reference]\ninit = true\nweight = 1.0"
        );
        let config = || {
            let mut c = tiny("KL-L", "alpha = 0.5", &sections);
            c.optimizer.epochs = 3;
            c.ppo.value_warmup_iterations = 0;
            c
        };
        let whole = train(
            config(),
            &dir.path().join(format!("whole{scale}")),
            false,
            None,
        );
        assert!(
            whole[0].kl.abs() < 1e-6,
            "scale {scale}: first KL {}",
            whole[0].kl
        );
        let last = whole.last().expect("rows").kl;
        assert!(
            last > 1e-6,
            "scale {scale}: the policy moved away: KL {last}"
        );
        if scale == 0.0 {
            let parts = dir.path().join("parts");
            train(config(), &parts, false, Some(1));
            // Every resume rebuilds the reference from the warm start: another file there
            // would be another reference mid-run.
            let kept = std::fs::read(&warm).expect("warm start");
            let other = saved_policy(dir.path(), "other.bpk", 7);
            std::fs::copy(&other, &warm).expect("replaced");
            let devices = devices(&config()).expect("devices");
            let message = Trainer::new(config(), data(), devices, &parts, true)
                .err()
                .expect("a replaced reference is refused")
                .to_string();
            assert!(
                message.contains("reference.init") && message.contains("other contents"),
                "{message}"
            );
            std::fs::write(&warm, kept).expect("restored");
            let resumed = train(config(), &parts, true, None);
            assert_eq!(without_time(&resumed), without_time(&whole));
        }
    }
}

fn without_time(rows: &[CurveRow]) -> Vec<CurveRow> {
    rows.iter()
        .map(|r| CurveRow {
            elapsed_s: 0.0,
            ..r.clone()
        })
        .collect()
}

/// Every parameter value of `policy`, in module order.
fn parameter_values(policy: &rtr::model::PolicyNetwork) -> Vec<f32> {
    struct Values(Vec<f32>);
    impl burn::module::ModuleVisitor for Values {
        fn visit_float<const D: usize>(
            &mut self,
            p: &burn::module::Param<burn::prelude::Tensor<D>>,
        ) {
            let v: Vec<f32> = p
                .val()
                .into_data()
                .convert::<f32>()
                .try_into_vec()
                .expect("f32");
            self.0.extend(v);
        }
    }
    let mut values = Values(Vec::new());
    policy.visit(&mut values);
    values.0
}

/// Every parameter value of the run's latest policy checkpoint, in module order.
fn policy_values(run: &Path, config: &TrainConfig) -> Vec<f32> {
    let dir = rtr::train::checkpoint::latest(run)
        .expect("pointer")
        .expect("a checkpoint");
    let device = rtr::backend::Backend::reference_device(false);
    parameter_values(
        &rtr::train::load_policy(&dir.join("policy.bpk"), &config.model, &device).expect("loads"),
    )
}

#[test]
fn runs_keep_the_checkpoints_asked_for_and_resume_whatever_the_count() {
    let config = |keep: Option<usize>| {
        let mut c = tiny("IL", "", "");
        c.optimizer.epochs = 4;
        c.run.keep_checkpoints = keep;
        c
    };
    let saved = |dir: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(dir.join("checkpoints"))
            .expect("checkpoints folder")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("iter-"))
            .collect();
        names.sort();
        names
    };
    let default = tempfile::tempdir().expect("temp dir");
    train(config(None), default.path(), false, None);
    assert_eq!(saved(default.path()), ["iter-000003", "iter-000004"]);

    let kept = tempfile::tempdir().expect("temp dir");
    train(config(Some(3)), kept.path(), false, Some(2));
    // Resumed asking for more: the count is how the run is stored, not what it is.
    train(config(Some(10)), kept.path(), true, None);
    assert_eq!(
        saved(kept.path()),
        ["iter-000001", "iter-000002", "iter-000003", "iter-000004"]
    );
}

#[test]
fn a_killed_and_resumed_run_equals_an_uninterrupted_one() {
    // With `ppo.target_kl` the policy's learning rate is state too: it moves at every step
    // after an iteration's first, and a resumed run must continue from where it was.
    let config = || {
        let mut c = tiny("RTR", "alpha = 0.5", "");
        c.optimizer.epochs = 3;
        c.ppo.minibatch = 1;
        c.ppo.target_kl = Some(0.01);
        c
    };
    let whole = tempfile::tempdir().expect("temp dir");
    let rows = train(config(), whole.path(), false, None);
    assert_eq!(rows.len(), 6, "3 iterations x 2 minibatches");
    let rates: Vec<f64> = rows.iter().map(|r| r.learning_rate).collect();
    assert!(
        rates.windows(2).any(|w| w[0] != w[1]) && rows.iter().any(|r| r.approx_kl > 0.0),
        "the adaptive rate moved: {rates:?}"
    );

    let parts = tempfile::tempdir().expect("temp dir");
    let first = train(config(), parts.path(), false, Some(1));
    assert_eq!(first.len(), 2);
    // Starting again without --resume would overwrite the run: refused.
    let devices = devices(&config()).expect("devices");
    let err = Trainer::new(config(), data(), devices, parts.path(), false)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("--resume"), "{err}");
    let resumed = train(config(), parts.path(), true, None);

    assert_eq!(without_time(&resumed), without_time(&rows));
    let on_disk = rtr::train::curves::read(&parts.path().join("curves.csv")).expect("csv");
    assert_eq!(without_time(&on_disk), without_time(&rows));
    let (resumed, whole) = (
        policy_values(parts.path(), &config()),
        policy_values(whole.path(), &config()),
    );
    assert!(
        resumed.len() > 1000 && resumed == whole,
        "parameters differ"
    );

    // The worker count is how a run executes, not what it is: resuming with another is
    // accepted, while another config is refused.
    let other = tempfile::tempdir().expect("temp dir");
    let mut one = config();
    one.run.devices = Some(1);
    train(one, other.path(), false, Some(1));
    let mut two = config();
    two.run.devices = Some(2);
    assert_eq!(train(two, other.path(), true, None).len(), 6);
    let mut changed = config();
    changed.seed += 1;
    let workers = rtr::train::session::devices(&changed).expect("devices");
    let err = Trainer::new(changed, data(), workers, other.path(), true)
        .err()
        .expect("another config is refused");
    assert!(err.to_string().contains("another config"), "{err}");
}

#[test]
fn a_diverging_run_stops_with_its_last_good_checkpoint() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A learning rate no network survives: the first step is finite, the parameters explode.
    let mut config = tiny("IL", "", "");
    config.optimizer.epochs = 5;
    config.optimizer.learning_rate = 1e30;
    let devices = devices(&config).expect("devices");
    let mut trainer =
        Trainer::new(config.clone(), data(), devices, dir.path(), false).expect("trainer");
    let err = trainer
        .run(&ProgressBar::hidden(), None)
        .expect_err("diverges");
    let text = err.to_string();
    assert!(
        text.contains("diverged") && text.contains("iter-"),
        "{text}"
    );
    let completed = trainer.state().iteration;
    assert!(
        completed >= 1,
        "at least one good step before the explosion"
    );
    // The last good checkpoint loads and is the last completed iteration.
    let latest = rtr::train::checkpoint::latest(dir.path())
        .expect("pointer")
        .expect("a checkpoint");
    assert!(
        latest.ends_with(format!("iter-{completed:06}")),
        "{}",
        latest.display()
    );
    let device = rtr::backend::Backend::reference_device(false);
    rtr::train::load_policy(&latest.join("policy.bpk"), &config.model, &device).expect("loads");
}

#[test]
fn two_devices_compute_the_one_device_loss_and_gradient() {
    let one = tempfile::tempdir().expect("temp dir");
    let two = tempfile::tempdir().expect("temp dir");
    let config = tiny("RTR", "alpha = 0.5", "[run]\nmax_iterations = 1");
    let mut alone = config.clone();
    alone.run.devices = Some(1);
    let single = train(alone, one.path(), false, None);
    let mut split = config.clone();
    split.run.devices = Some(2);
    let double = train(split, two.path(), false, None);
    // More devices than scenes: the idle ones are left out, the step is the same.
    let many = tempfile::tempdir().expect("temp dir");
    let mut wide = config;
    wide.run.devices = Some(5);
    let spread = train(wide, many.path(), false, None);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * a.abs().max(b.abs()).max(1e-6);
    let (a, b) = (&single[0], &double[0]);
    assert!(close(a.loss, b.loss), "loss {} vs {}", a.loss, b.loss);
    assert!(close(a.il_loss, b.il_loss) && close(a.policy_loss, b.policy_loss));
    assert!(
        close(a.policy_grad_norm, b.policy_grad_norm),
        "gradient norm {} vs {}",
        a.policy_grad_norm,
        b.policy_grad_norm
    );
    let c = &spread[0];
    assert!(close(a.loss, c.loss) && close(a.policy_grad_norm, c.policy_grad_norm));
}

/// A warm start begins from the given policy: with the whole run in the value warm-up, the
/// policy stays exactly the initial one while the value network learns; after the warm-up the
/// policy moves. A missing initial policy is named.
#[test]
fn a_warm_started_run_begins_from_its_initial_policy_and_warms_up_the_value() {
    let dir = tempfile::tempdir().expect("temp dir");
    let init = reference_policy(dir.path());
    let run = |warmup: usize, out: &Path| {
        let mut config = tiny("RTR", "alpha = 0.5", "");
        config.init = Some(rtr::train::InitConfig {
            policy: init.clone().into(),
            std_from_logs: false,
            std_scale: [1.0, 1.0],
            add_agent_edge_motion: false,
            agent_edge_motion_scale: 1.0,
        });
        config.ppo.value_warmup_iterations = warmup;
        config.optimizer.epochs = 2;
        let rows = train(config.clone(), out, false, None);
        (rows, policy_values(out, &config))
    };
    let device = rtr::backend::Backend::reference_device(false);
    let initial = parameter_values(
        &rtr::train::load_policy(Path::new(&init), &tiny("IL", "", "").model, &device)
            .expect("initial policy"),
    );

    let warming = dir.path().join("warming");
    let (rows, policy) = run(2, &warming);
    assert_eq!(policy, initial, "the policy moved during the value warm-up");
    assert!(
        rows.iter()
            .all(|r| r.il_loss == 0.0 && r.policy_loss == 0.0 && r.value_loss > 0.0),
        "{rows:?}"
    );
    assert!(rows.iter().all(|r| r.value_grad_norm > 0.0), "{rows:?}");

    let after = dir.path().join("after");
    let (rows, policy) = run(1, &after);
    assert_ne!(policy, initial, "the policy never moved after the warm-up");
    assert!(rows.last().is_some_and(|r| r.il_loss > 0.0), "{rows:?}");

    // With std_from_logs the warm start keeps its mean, and its sigma becomes the RMS error of
    // that mean against the nominal training logs times std_scale, the same for every agent.
    let calibrated = dir.path().join("calibrated");
    let mut config = tiny("RTR", "alpha = 0.5", "");
    config.init = Some(rtr::train::InitConfig {
        policy: init.clone().into(),
        std_from_logs: true,
        std_scale: [1.0, 0.5],
        add_agent_edge_motion: false,
        agent_edge_motion_scale: 1.0,
    });
    config.ppo.value_warmup_iterations = 2;
    config.optimizer.epochs = 2;
    train(config.clone(), &calibrated, false, None);
    let load = |path: &Path| rtr::train::load_policy(path, &config.model, &device).expect("loads");
    let first = load(Path::new(&init));
    let latest = rtr::train::checkpoint::latest(&calibrated)
        .expect("pointer")
        .expect("a checkpoint");
    let warmed = load(&latest.join("policy.bpk"));
    let scenes: Vec<&rtr::scene::Scene> = data().nominal.iter().collect();
    let (rms, _) =
        rtr::train::imitation::logged_action_rms(&first, &scenes, &config.limits, 16, &device)
            .expect("rms");
    let batch = rtr::scene::SceneBatch::from_scenes(&scenes[..1], &device).expect("batch");
    let act = |p: &rtr::model::PolicyNetwork| {
        let lanes = rtr::model::LaneInput::from_batch(&batch, p.config());
        let frames = rtr::sim::logged_frames(&batch, batch.history_steps);
        let agents = rtr::model::AgentInput::from_frames(&batch, &frames, p.config());
        let d = p.forward(&agents, &lanes, &p.encode_lanes(&lanes));
        let v = |t: burn::prelude::Tensor<3>| -> Vec<f32> {
            t.into_data().convert::<f32>().try_into_vec().expect("f32")
        };
        let mask: Vec<bool> = agents.mask.into_data().try_into_vec_as().expect("mask");
        (v(d.mean), v(d.log_std), mask)
    };
    let ((mean0, _, _), (mean1, log_std, mask)) = (act(&first), act(&warmed));
    assert_eq!(mean0, mean1);
    assert!(mask.iter().any(|&m| m));
    for (slot, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        for k in 0..2 {
            let sigma = (log_std[slot * 2 + k] as f64).exp();
            let expected = rms[k] * [1.0, 0.5][k];
            assert!(
                (sigma / expected - 1.0).abs() < 1e-3,
                "{sigma} vs {expected}"
            );
        }
    }

    let mut missing = tiny("RTR", "alpha = 0.5", "");
    missing.init = Some(rtr::train::InitConfig {
        policy: dir.path().join("no-such-policy.bpk"),
        std_from_logs: false,
        std_scale: [1.0, 1.0],
        add_agent_edge_motion: false,
        agent_edge_motion_scale: 1.0,
    });
    let workers = devices(&missing).expect("devices");
    let err = Trainer::new(missing, data(), workers, &dir.path().join("x"), false)
        .err()
        .expect("a missing initial policy is refused");
    assert!(err.to_string().contains("no-such-policy.bpk"), "{err}");

    // A scaled sigma the head cannot express is refused, not clamped.
    let mut tiny_sigma = tiny("RTR", "alpha = 0.5", "");
    tiny_sigma.init = Some(rtr::train::InitConfig {
        policy: init.clone().into(),
        std_from_logs: true,
        std_scale: [1.0, 1e-6],
        add_agent_edge_motion: false,
        agent_edge_motion_scale: 1.0,
    });
    let workers = devices(&tiny_sigma).expect("devices");
    let err = Trainer::new(tiny_sigma, data(), workers, &dir.path().join("y"), false)
        .err()
        .expect("an inexpressible sigma is refused");
    assert!(
        err.to_string().contains("steering sigma") && err.to_string().contains("init.std_scale"),
        "{err}"
    );
    assert!(
        !dir.path().join("y").exists(),
        "a refused run wrote its folder"
    );
}

/// The sweep's first point, lambda = alpha = 0, is IL inside the RTR loop: the value loss is
/// weighted by lambda, so during the value warm-up no term has weight and nothing may move;
/// after it, only the imitation term trains the policy.
#[test]
fn rtr_at_lambda_zero_waits_out_the_warm_up_then_imitates() {
    let dir = tempfile::tempdir().expect("temp dir");
    let init = reference_policy(dir.path());
    let mut config = tiny("RTR", "lambda = 0.0\nalpha = 0.0", "");
    config.init = Some(rtr::train::InitConfig {
        policy: init.clone().into(),
        std_from_logs: false,
        std_scale: [1.0, 1.0],
        add_agent_edge_motion: false,
        agent_edge_motion_scale: 1.0,
    });
    config.ppo.value_warmup_iterations = 1;
    config.optimizer.epochs = 2;
    let warming = dir.path().join("warming");
    let mut first = config.clone();
    first.optimizer.epochs = 1;
    let rows = train(first.clone(), &warming, false, None);
    assert_eq!(rows.len(), 1);
    assert_eq!(
        (
            rows[0].loss,
            rows[0].policy_grad_norm,
            rows[0].value_grad_norm
        ),
        (0.0, 0.0, 0.0),
        "{rows:?}"
    );
    let device = rtr::backend::Backend::reference_device(false);
    let initial = parameter_values(
        &rtr::train::load_policy(Path::new(&init), &config.model, &device).expect("initial"),
    );
    assert_eq!(policy_values(&warming, &first), initial);

    let run = dir.path().join("run");
    let rows = train(config.clone(), &run, false, None);
    let last = rows.last().expect("rows");
    assert!(
        last.il_loss > 0.0 && last.policy_grad_norm > 0.0,
        "{rows:?}"
    );
    assert_eq!((last.policy_loss, last.value_loss), (0.0, 0.0), "{rows:?}");
    assert_ne!(policy_values(&run, &config), initial);
}

/// A model loaded with another run's [model] (a warm start beside a run file of the paper's
/// size) is refused with what to change, not as a broken file.
#[test]
fn a_model_loaded_with_another_shape_names_the_model_section() {
    let device = rtr::backend::Backend::reference_device(false);
    let small = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/il/policy.bpk");
    let paper_size = rtr::model::ModelConfig::default();
    let err = rtr::train::load_policy(&small, &paper_size, &device).expect_err("32 into 128");
    let text = err.to_string();
    assert!(
        text.contains("models/il/policy.bpk")
            && text.contains("[model]")
            && text.contains("config.toml")
            && text.contains("shape mismatch")
            && text.contains("expected [")
            && !text.contains("Shape {")
            && !text.contains("this version of rtr"),
        "{text}"
    );
    assert!(text.len() < 600, "one mismatch is named, not all: {text}");
}

/// Resume refuses what it cannot continue: a folder without a checkpoint (empty, or holding
/// only a config), a `state.json` edited to claim another position, a tensor file changed
/// after it was written; and a policy with NaN weights is refused by name wherever it is
/// loaded.
#[test]
fn resume_and_loading_refuse_missing_tampered_and_corrupted_checkpoints() {
    let config = || tiny("IL", "", "");
    let trainer = |dir: &Path| {
        let workers = devices(&config()).expect("devices");
        Trainer::new(config(), data(), workers, dir, true).map(|_| ())
    };
    let root = tempfile::tempdir().expect("temp dir");
    let empty = root.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    let err = trainer(&empty).expect_err("nothing to resume");
    assert!(err.to_string().contains("no checkpoint to resume"), "{err}");
    std::fs::write(empty.join("config.toml"), "method = \"IL\"\n").expect("write");
    let err = trainer(&empty).expect_err("a config alone is nothing to resume");
    assert!(err.to_string().contains("no checkpoint to resume"), "{err}");
    let err = trainer(&root.path().join("missing")).expect_err("no folder");
    assert!(err.to_string().contains("no checkpoint to resume"), "{err}");

    let run = root.path().join("run");
    train(config(), &run, false, Some(1));
    let checkpoint = rtr::train::checkpoint::latest(&run)
        .expect("pointer")
        .expect("a checkpoint");
    trainer(&run).expect("an untouched checkpoint resumes");

    let state_path = checkpoint.join("state.json");
    let state = std::fs::read_to_string(&state_path).expect("state");
    let tampered = state.replace("\"iteration\": 1,", "\"iteration\": 1000000000000,");
    assert_ne!(tampered, state, "{state}");
    std::fs::write(&state_path, &tampered).expect("write");
    let err = trainer(&run).expect_err("a tampered position");
    let text = err.to_string();
    assert!(
        text.contains("state.json") && text.contains("1000000000000"),
        "{text}"
    );
    std::fs::write(&state_path, &state).expect("restore");

    let policy_path = checkpoint.join("policy.bpk");
    let mut bytes = std::fs::read(&policy_path).expect("policy");
    let n = bytes.len();
    bytes[n - 8..].fill(0xFF);
    std::fs::write(&policy_path, &bytes).expect("corrupt");
    let err = trainer(&run).expect_err("a corrupted tensor file");
    let text = err.to_string();
    assert!(
        text.contains("policy.bpk") && text.contains("sha256"),
        "{text}"
    );
    // The same bytes without a state to check them against (copied out of the checkpoint):
    // NaN weights, refused by name.
    let device = rtr::backend::Backend::reference_device(false);
    let loose = tempfile::tempdir().expect("temp dir");
    let policy_path = loose.path().join("policy.bpk");
    std::fs::write(&policy_path, &bytes).expect("copy");
    let err =
        rtr::train::load_policy(&policy_path, &config().model, &device).expect_err("NaN weights");
    let text = err.to_string();
    assert!(
        text.contains("policy.bpk") && text.contains("parameter") && text.contains("NaN"),
        "{text}"
    );
}

#[test]
fn run_files_with_mistakes_are_named() {
    let err = TrainConfig::from_toml_str("method = \"RTR\"\n[ppo]\ngama = 0.9\n", "bad.toml")
        .expect_err("typo");
    let text = err.to_string();
    assert!(
        text.contains("bad.toml") && text.contains("line 3") && text.contains("gama"),
        "{text}"
    );
    let err = TrainConfig::from_toml_str("method = \"IL\"\nalpha = 0.3\n", "il.toml")
        .expect_err("IL has no long-tail logs");
    assert!(err.to_string().contains("alpha"), "{err}");
    let err = TrainConfig::from_toml_str(
        "method = \"IL\"\n[imitation.perturbation]\nlateral_m = 5.0\nheading_rad = 0.01\n",
        "il.toml",
    )
    .expect_err("a perturbation wider than a lane");
    assert!(
        err.to_string().contains("imitation.perturbation") && err.to_string().contains("lateral_m"),
        "{err}"
    );
    let err = TrainConfig::from_toml_str(
        "method = \"IL\"\n[imitation]\nagent_dropout = 1.0\n",
        "il.toml",
    )
    .expect_err("every agent dropped");
    assert!(
        err.to_string().contains("imitation.agent_dropout") && err.to_string().contains("[0, 1)"),
        "{err}"
    );
    let err = TrainConfig::from_toml_str(
        "method = \"IL\"\n[[data.a9_bends]]\ncurvature = 0.05\nweight = 0.1\n",
        "il.toml",
    )
    .expect_err("a 20 m radius");
    assert!(
        err.to_string().contains("data.a9_bends.curvature") && err.to_string().contains("0.01"),
        "{err}"
    );
    let err = TrainConfig::from_toml_str(
        "method = \"IL\"\n[[data.a9_bends]]\ncurvature = 0.001\nweight = -1.0\n",
        "il.toml",
    )
    .expect_err("a negative weight");
    assert!(err.to_string().contains("data.a9_bends.weight"), "{err}");
    let err = TrainConfig::from_toml_str(
        "method = \"IL\"\n[[data.a9_bends]]\ncurvature = 0.001\n",
        "il.toml",
    )
    .expect_err("no weight");
    assert!(err.to_string().contains("weight"), "{err}");
    for rho in ["[1.0, 0.0]", "[0.5, -0.5]", "[nan, 0.0]"] {
        let err = TrainConfig::from_toml_str(
            &format!("method = \"RTR\"\n[ppo]\nnoise_correlation = {rho}\n"),
            "rtr.toml",
        )
        .expect_err("not a correlation in [0, 1)");
        assert!(
            err.to_string().contains("ppo.noise_correlation") && err.to_string().contains("[0, 1)"),
            "{err}"
        );
    }
    for kl in ["0.0", "-0.01", "nan"] {
        let err = TrainConfig::from_toml_str(
            &format!("method = \"RL\"\n[ppo]\ntarget_kl = {kl}\n"),
            "rl.toml",
        )
        .expect_err("not a KL target > 0");
        assert!(err.to_string().contains("ppo.target_kl"), "{err}");
    }
}

#[test]
fn a9_bends_are_recorded_sources_of_their_own() {
    use rand::SeedableRng;
    use rtr::train::{A9Bend, InitialState};
    let config = DataConfig {
        nominal_limit: Some(6),
        a9_weight: 0.0,
        a9_bends: vec![A9Bend {
            curvature: -0.002,
            weight: 1.0,
        }],
        ..DataConfig::default()
    };
    let data = TrainingData::load(common::a9(), &config, false).expect("bent sources load");
    assert_eq!(data.nominal.len(), 12);
    assert_eq!(data.nominal_sources.len(), 2);
    // The warm start's sigma is measured on the recorded scenes, never on their bent copies.
    assert_eq!(data.bent, 6..12);
    let recorded: Vec<_> = data.recorded().map(|s| s.id.clone()).collect();
    assert_eq!(recorded.len(), 6);
    assert!(
        recorded.iter().all(|id| !id.contains("~bend")),
        "{recorded:?}"
    );
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    // The A9 as recorded has weight 0: every draw is a bent scene, of the same recorded window.
    for state in data.sample(&mut rng, 20, 0.0) {
        let InitialState::Nominal(k) = state else {
            panic!("{state:?}")
        };
        assert!(k >= 6, "drew the unbent scene {k}");
        let id = &data.nominal[k].id;
        assert_eq!(id, &format!("{}~bend-0.002", data.nominal[k - 6].id));
    }
}

#[test]
fn every_shipped_experiment_file_is_a_valid_run() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mut methods = Vec::new();
    let mut folders = vec![root];
    let mut files = 0;
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("experiments folder") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|e| e == "toml") {
                // A study's own scenario families (`rtr scenarios generate --families`).
                if folder.components().any(|c| c.as_os_str() == "families") {
                    rtr::scenario::LogicalScenario::from_toml_file(&path)
                        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                    continue;
                }
                let config = TrainConfig::from_toml_file(&path)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                methods.push(config.method);
                files += 1;
            }
        }
    }
    // experiments/main alone holds 12 (paper and small budget).
    assert!(files > 12, "only {files} run files found");
    for method in rtr::train::Method::ALL {
        assert!(
            methods.contains(&method),
            "no experiment trains {}",
            method.name()
        );
    }
}

/// A `[B, N, T]` tensor's values, row-major.
fn host(t: burn::prelude::Tensor<3>) -> Vec<f32> {
    t.into_data().convert::<f32>().try_into_vec().expect("f32")
}

/// A `[B, N, T]` mask's values, row-major.
fn host_mask(t: burn::prelude::Tensor<3, burn::tensor::Bool>) -> Vec<bool> {
    t.into_data().try_into_vec_as().expect("bool")
}

/// Collects PPO experience with a fresh tiny RL policy from two nominal and two long-tail
/// initial states, `steps` steps each, with the PPO settings `ppo` edits (e.g. the exploration
/// noise's correlation), once per noise seed of `seeds`.
fn collected(
    ppo: impl Fn(&mut rtr::train::config::PpoConfig),
    steps: usize,
    seeds: std::ops::Range<u64>,
) -> (
    TrainConfig,
    rtr::model::PolicyNetwork,
    rtr::model::ValueNetwork,
    Vec<rtr::train::experience::Experience>,
) {
    use rtr::model::{PolicyNetwork, ValueNetwork};

    let mut config = tiny("RL", "alpha = 0.5", "");
    ppo(&mut config.ppo);
    let device = rtr::backend::Backend::reference_device(false);
    let policy = PolicyNetwork::new(&config.model, &device);
    let value = ValueNetwork::new(&config.model, &device);
    let experience = collected_by(&config.ppo, &policy, &value, steps, seeds);
    (config, policy, value, experience)
}

/// What [`collected`] collects, with given networks.
fn collected_by(
    ppo: &rtr::train::config::PpoConfig,
    policy: &rtr::model::PolicyNetwork,
    value: &rtr::model::ValueNetwork,
    steps: usize,
    seeds: std::ops::Range<u64>,
) -> Vec<rtr::train::experience::Experience> {
    let states: Vec<_> = (0..4)
        .map(|k| {
            if k % 2 == 0 {
                rtr::train::InitialState::Nominal(0)
            } else {
                rtr::train::InitialState::LongTail(k / 2)
            }
        })
        .collect();
    collected_from(data(), &states, ppo, policy, value, steps, seeds)
}

/// What [`collected_by`] collects, from `states` of `data`.
fn collected_from(
    data: &TrainingData,
    states: &[rtr::train::InitialState],
    ppo: &rtr::train::config::PpoConfig,
    policy: &rtr::model::PolicyNetwork,
    value: &rtr::model::ValueNetwork,
    steps: usize,
    seeds: std::ops::Range<u64>,
) -> Vec<rtr::train::experience::Experience> {
    use rtr::sim::{Dynamics, MapCaches};
    use rtr::train::experience::{CollectNetworks, RewardSettings, collect};

    let device = rtr::backend::Backend::reference_device(false);
    let mut caches = MapCaches::default();
    let nets = CollectNetworks {
        policy,
        value,
        reference: None,
    };
    let rewards = RewardSettings {
        shaping: None,
        kl_weight: None,
    };
    let parts = data.parts(states);
    seeds
        .flat_map(|seed| parts.iter().map(move |part| (seed, part)))
        .map(|(seed, part)| {
            collect(
                part,
                &nets,
                &device,
                &Dynamics::bicycle(0.5),
                &mut caches,
                Some(steps),
                ppo,
                &rewards,
                seed,
            )
            .expect("collects")
        })
        .collect()
}

/// Before any parameter step, re-evaluating the stored observations gives the collection's own
/// log-probabilities: every ratio is 1, so the surrogate is minus the summed advantages (the
/// observations, edges included, are kept from the rollout, not rebuilt). With correlated
/// exploration noise the same holds for the Normals conditioned on each agent's previous noise.
#[test]
fn ppo_reevaluates_the_collected_observations_exactly() {
    use rtr::train::ppo::{AdvantageScale, ppo_terms};

    for rho in [[0.0, 0.0], [0.9, 0.5]] {
        let (config, policy, value, experience) = collected(|p| p.noise_correlation = rho, 4, 7..8);
        for experience in experience {
            let correlated = rho != [0.0, 0.0];
            assert_eq!(
                experience.previous_noise.len(),
                if correlated { 4 } else { 0 }
            );
            let terms = ppo_terms(
                &policy,
                &value,
                &experience,
                &config.ppo,
                AdvantageScale::IDENTITY,
                false,
            );
            let surrogate = terms.policy.sum.into_scalar::<f64>();
            let advantages = (experience.advantages.clone() * experience.alive.clone().float())
                .sum()
                .into_scalar::<f64>();
            assert!(terms.policy.count > 0);
            assert!(
                (surrogate + advantages).abs() <= 1e-5 * advantages.abs().max(1.0),
                "rho {rho:?}: surrogate {surrogate} vs -sum(A) {}",
                -advantages
            );
            assert_eq!(terms.clipped, 0);
        }
    }
}

/// One agent's end of episode in two collections of the same rollout under two reward
/// settings: the value left at its last alive step, how much that step's return changed, and
/// that return in the first.
struct EpisodeEnd {
    value_left: f64,
    change: f64,
    return_before: f64,
}

/// Per agent of `before` and `after`, the same rollout collected under two reward settings:
/// its [`EpisodeEnd`]. Checks the rollouts sampled the same actions and that every earlier
/// return of the agent moved by the last step's change, discounted by `gamma` per step.
fn episode_ends(
    before: &rtr::train::experience::Experience,
    after: &rtr::train::experience::Experience,
    gamma: f64,
) -> Vec<EpisodeEnd> {
    assert_eq!(
        host(before.old_log_prob.clone()),
        host(after.old_log_prob.clone())
    );
    let [b, n, steps] = after.alive.dims();
    let alive = host_mask(after.alive.clone());
    let (adv_before, ret_before, ret_after) = (
        host(before.advantages.clone()),
        host(before.returns.clone()),
        host(after.returns.clone()),
    );
    let mut ends = Vec::new();
    for agent in 0..b * n {
        let row = agent * steps;
        let Some(last) = (0..steps).rev().find(|&t| alive[row + t]) else {
            continue;
        };
        let change = (ret_after[row + last] - ret_before[row + last]) as f64;
        for t in 0..last {
            let earlier = (ret_after[row + t] - ret_before[row + t]) as f64;
            let expect = gamma.powi((last - t) as i32) * change;
            assert!(
                (earlier - expect).abs() < 1e-4,
                "step {t}: {earlier} vs {expect}"
            );
        }
        ends.push(EpisodeEnd {
            value_left: (ret_before[row + last] - adv_before[row + last]) as f64,
            change,
            return_before: ret_before[row + last] as f64,
        });
    }
    ends
}

/// `ppo.bootstrap_exits` changes nothing of the rollout, and only the returns of agents that
/// leave the map: by gamma^(k+1) V(s) of the state s they left from, k steps before. The
/// scene-level returns stay the sums of the agents' (GAE lambda 1), exits included.
#[test]
fn exits_are_bootstrapped_only_where_agents_leave_the_map() {
    // Recorded scenes, where cars near the end of the recorded road leave it within seconds.
    let recorded = TrainingData::load(
        common::a9(),
        &DataConfig {
            nominal_limit: Some(24),
            ..DataConfig::default()
        },
        false,
    )
    .expect("training data");
    let states: Vec<_> = (0..24).map(rtr::train::InitialState::Nominal).collect();
    let (mut config, policy, value, _) = collected(|_| {}, 1, 0..1);
    let terminated = collected_from(&recorded, &states, &config.ppo, &policy, &value, 10, 3..4);
    config.ppo.bootstrap_exits = true;
    let truncated = collected_from(&recorded, &states, &config.ppo, &policy, &value, 10, 3..4);
    let gamma = config.ppo.gamma;
    let mut exits = 0;
    for (off, on) in terminated.iter().zip(&truncated) {
        for end in episode_ends(off, on, gamma) {
            if end.change.abs() > 1e-6 {
                exits += 1;
                assert!(
                    (end.change - gamma * end.value_left).abs() < 1e-4,
                    "{} vs {}",
                    end.change,
                    end.value_left
                );
            }
        }
        let [b, n, steps] = on.alive.dims();
        let (alive, ret_on) = (host_mask(on.alive.clone()), host(on.returns.clone()));
        let scene_returns = host(on.scene_returns.clone());
        for scene in 0..b {
            for t in 0..steps {
                let agents: f64 = (0..n)
                    .map(|k| (scene * n + k) * steps + t)
                    .filter(|&i| alive[i])
                    .map(|i| ret_on[i] as f64)
                    .sum();
                let joint = scene_returns[scene * steps + t] as f64;
                assert!(
                    (joint - agents).abs() < 1e-3,
                    "scene {scene} step {t}: {joint} vs {agents}"
                );
            }
        }
    }
    assert!(exits > 0, "no agent left the map in 10 steps");
}

/// `ppo.at_fault_collisions` changes nothing of the rollout, and only the returns of agents
/// struck from behind: their last transition's -1 becomes 0 plus gamma V(s) of the state they
/// were struck from (a truncation), and every earlier return moves by that, discounted.
#[test]
fn collisions_struck_from_behind_cost_nothing_only_when_asked() {
    let (mut config, policy, value, everyone) = collected(|_| {}, 10, 0..6);
    config.ppo.at_fault_collisions = true;
    let at_fault = collected_by(&config.ppo, &policy, &value, 10, 0..6);
    let gamma = config.ppo.gamma;
    let (mut waived, mut penalised) = (0, 0);
    for (off, on) in everyone.iter().zip(&at_fault) {
        assert_eq!(off.stats.collided, on.stats.collided);
        for end in episode_ends(off, on, gamma) {
            if end.change.abs() > 1e-6 {
                waived += 1;
                assert!(
                    (end.change - (1.0 + gamma * end.value_left)).abs() < 1e-4,
                    "{} vs 1 + gamma x {}",
                    end.change,
                    end.value_left
                );
            } else if end.return_before < -0.5 {
                penalised += 1;
            }
        }
    }
    assert!(waived > 0, "no agent was struck from behind");
    assert!(penalised > 0, "no infraction stayed penalised");
}

/// With `ppo.explore_steering = false` every collected steering is the policy's mean and every
/// stored log-probability is the acceleration's density alone (the steering has no term in
/// PPO's ratios).
#[test]
fn acceleration_only_exploration_steers_with_the_mean_and_scores_acceleration() {
    use rtr::model::LaneInput;

    let (_, policy, _, experience) = collected(|p| p.explore_steering = false, 4, 7..8);
    let mut acceleration_noise = 0.0f64;
    for exp in &experience {
        let alive = host_mask(exp.alive.clone());
        let old = host(exp.old_log_prob.clone());
        let lanes = LaneInput::from_batch(&exp.batch, policy.config());
        let encoded = policy.encode_lanes(&lanes);
        for (t, (agents, action)) in exp.observations.iter().zip(&exp.actions).enumerate() {
            let dist = policy.forward(agents, &lanes, &encoded);
            let [b, n, _] = action.dims();
            let noise = host((action.clone() - dist.mean.clone()) / dist.std());
            let acceleration = host(
                dist.log_prob_of(action.clone(), [true, false])
                    .unsqueeze_dim(2),
            );
            for i in 0..b * n {
                let k = i * exp.steps + t;
                if !alive[k] {
                    continue;
                }
                assert_eq!(noise[i * 2 + 1], 0.0, "agent-step {k} steered off its mean");
                acceleration_noise += (noise[i * 2] as f64).powi(2);
                assert!(
                    (old[k] - acceleration[i]).abs() < 1e-4,
                    "agent-step {k}: stored {} vs the acceleration's {}",
                    old[k],
                    acceleration[i]
                );
            }
        }
    }
    assert!(acceleration_noise > 1.0, "the acceleration was not sampled");
}

/// The sampled actions' standardised noise (a - mu) / sigma, under the policy that sampled
/// them, has unit variance, and its correlation from one step to the next is the control's
/// `ppo.noise_correlation`: about 0 by default, and 0.9 for acceleration and 0 for steering
/// when asked for.
#[test]
fn correlated_exploration_holds_each_agents_noise_over_steps() {
    for rho in [[0.0, 0.0], [0.9, 0.0]] {
        let (_, policy, _, experience) = collected(|p| p.noise_correlation = rho, 10, 0..8);
        // Per control: sum of z^2, its count, sum of z_t z_(t+1), its count.
        let mut sums = [[0.0f64; 4]; 2];
        for exp in &experience {
            let lanes = policy.encode_lanes(&exp.lanes);
            let noise: Vec<Vec<f32>> = exp
                .observations
                .iter()
                .zip(&exp.actions)
                .map(|(agents, action)| {
                    let dist = policy.forward(agents, &exp.lanes, &lanes);
                    host((action.clone() - dist.mean.clone()) / dist.std())
                })
                .collect();
            // Every agent that acts at the first step, over all steps: the noise runs on after
            // an agent's episode ends, and keeping only the steps it survives would keep the
            // small noises (a large correlated one drives it off the road).
            let [_, _, steps] = exp.alive.dims();
            let alive = host_mask(exp.alive.clone());
            for agent in (0..alive.len() / steps).filter(|a| alive[a * steps]) {
                for (c, sum) in sums.iter_mut().enumerate() {
                    let z = |t: usize| noise[t][agent * 2 + c] as f64;
                    for t in 0..steps {
                        sum[0] += z(t) * z(t);
                        sum[1] += 1.0;
                        if t + 1 < steps {
                            sum[2] += z(t) * z(t + 1);
                            sum[3] += 1.0;
                        }
                    }
                }
            }
        }
        for (c, sum) in sums.iter().enumerate() {
            let variance = sum[0] / sum[1];
            let correlation = sum[2] / sum[3] / variance;
            assert!(sum[3] > 3000.0, "{} pairs", sum[3]);
            // Eight noise seeds: at rho 0.9 an agent's ten steps are about two independent
            // draws.
            assert!(
                (variance - 1.0).abs() < 0.12,
                "rho {rho:?}, control {c}: variance {variance}"
            );
            assert!(
                (correlation - rho[c]).abs() < 0.05,
                "rho {rho:?}, control {c}: lag-1 correlation {correlation}"
            );
        }
    }
}

/// The warm start's sigma from the logs is set through the action head's output bias: every
/// parameter stays trained, as after loading a checkpoint (the bias was once left out, so a
/// resumed run trained what the uninterrupted one froze).
#[test]
fn sigma_from_the_logs_leaves_every_parameter_trained() {
    struct Untracked(Vec<String>);
    impl burn::module::ModuleVisitor for Untracked {
        fn visit_float<const D: usize>(
            &mut self,
            p: &burn::module::Param<burn::prelude::Tensor<D>>,
        ) {
            if !p.is_require_grad() {
                self.0.push(format!("{:?}", p.val().dims()));
            }
        }
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let file = reference_policy(dir.path());
    let config = tiny("IL", "", "");
    let device = rtr::backend::Backend::reference_device(true);
    let loaded = rtr::train::checkpoint::load_policy(Path::new(&file), &config.model, &device)
        .expect("load");
    let mut untracked = Untracked(Vec::new());
    loaded.visit(&mut untracked);
    assert!(untracked.0.is_empty(), "loaded: {:?}", untracked.0);
    loaded
        .with_constant_std([0.86, 0.004])
        .visit(&mut untracked);
    assert!(untracked.0.is_empty(), "with sigma set: {:?}", untracked.0);
}
