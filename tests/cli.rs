//! The `rtr` binary as a user runs it.

use std::process::Command;

fn rtr(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rtr"))
        .args(args)
        .output()
        .expect("the rtr binary runs")
}

#[test]
fn data_summary_json_has_the_documented_fields() {
    let out = rtr(&["data", "summary", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["vehicles"], 453);
    assert_eq!(v["driving_lanes"], 6);
    assert!((v["road_length_m"].as_f64().unwrap() - 266.28).abs() < 0.01);
    assert!((v["duration_s"].as_f64().unwrap() - 541.4).abs() < 0.1);
    for key in [
        "lane_graph_nodes",
        "train_scenes",
        "test_scenes",
        "logged_offroad_pct",
        "logged_collision_pct",
    ] {
        assert!(v[key].is_number(), "{key} missing in {v}");
    }
    assert!(v["train_scenes"].as_u64().unwrap() > v["test_scenes"].as_u64().unwrap());
    // Every closing event of the logged drivers has exactly one response.
    let closing = &v["logged_closing"];
    let count = |key: &str| {
        closing[key]
            .as_u64()
            .unwrap_or_else(|| panic!("{key} in {closing}"))
    };
    assert!(count("events") > 0, "{closing}");
    assert_eq!(
        count("events"),
        count("lane_changes") + count("braked") + count("neither")
    );
}

#[test]
fn render_writes_png_and_svg() {
    let dir = tempfile::tempdir().expect("temp dir");
    let prefix = dir.path().join("scene");
    let out = rtr(&[
        "render", "--split", "test", "--index", "3", "--width", "800", "--out",
    ]
    .iter()
    .copied()
    .chain([prefix.to_str().unwrap()])
    .collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let png = std::fs::read(prefix.with_extension("png")).expect("png written");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let svg = std::fs::read_to_string(prefix.with_extension("svg")).expect("svg written");
    assert!(svg.contains("<svg") && svg.contains("<polygon"));
}

/// `rtr render --animate` on an A9 test scene with the shipped IL model. Frame rule: one frame
/// per step of the scene's window, its history, the current step, then every simulated step
/// (`Scene::steps()`: 4 + 1 + 12 = 17 frames), `--width` wide and as tall as the fixed view of
/// the window (`frame_size` within the `window_focus` of every car in the log and in the same
/// rollout made here). The cars move: every frame differs from the one before above the
/// progress bar along the bottom edge. An --out that is not a .gif, and the policy flags
/// without --animate, are refused naming the flags.
#[test]
fn render_animate_writes_a_gif_of_a_policy_rollout() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("rollout.gif");
    let out = rtr(&[
        "render",
        "--animate",
        "--checkpoint",
        "models/il",
        "--index",
        "3",
        "--width",
        "240",
        "--out",
        path.to_str().expect("utf-8 path"),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("17 frames") && stdout.contains("IL (models/il)"),
        "{stdout}"
    );

    let data = rtr::data::A9Dataset::load(&rtr::data::a9::default_dir()).expect("A9 loads");
    let split = data
        .scenes(&rtr::data::SceneConfig::default())
        .expect("scenes");
    let scene = &split.test[3];
    let device = rtr::backend::Backend::NdArray
        .device(false)
        .expect("CPU device");
    let il = rtr::eval::TrainedPolicy::load("models/il".as_ref(), &device).expect("IL loads");
    let set = rtr::eval::EvalScenes::real(vec![scene.clone()]);
    let rollout =
        rtr::eval::watch_rollout(&il.network, &il.dynamics, &set, 0, &device).expect("rollout");
    let opts = rtr::render::RenderOptions {
        width_px: 240,
        focus: rtr::render::window_focus(&[scene, &rollout.scene], &[]),
        ..Default::default()
    };
    let (width, height) = rtr::render::frame_size(&scene.map, &opts).expect("view");
    assert_eq!(width, 240);

    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let file = std::fs::File::open(&path).expect("gif written");
    let mut decoder = options.read_info(file).expect("a GIF");
    assert_eq!(
        (decoder.width().into(), decoder.height().into()),
        (width, height)
    );
    let mut frames = Vec::new();
    while let Some(frame) = decoder.read_next_frame().expect("frame decodes") {
        assert_eq!((frame.width.into(), frame.height.into()), (width, height));
        frames.push(frame.buffer.to_vec());
    }
    assert_eq!(scene.steps(), 17);
    assert_eq!(frames.len(), scene.steps());
    let bar_px = (height / 40).max(3);
    let above_bar = ((height - bar_px) * width * 4) as usize;
    for (k, pair) in frames.windows(2).enumerate() {
        assert_ne!(
            pair[0][..above_bar],
            pair[1][..above_bar],
            "frames {k} and {}",
            k + 1
        );
    }

    let out = rtr(&["render", "--animate", "--out", "scene.png"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--out scene.png") && err.contains("--animate"),
        "{err}"
    );
    assert!(err.contains(".gif"), "{err}");
    let out = rtr(&["render", "--idm", "--out", "scene.png"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--animate"), "{err}");
}

#[test]
fn bad_arguments_fail_with_a_message() {
    let out = rtr(&["render", "--index", "100000", "--out", "unused.png"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--index 100000"), "{err}");

    let out = rtr(&["data", "summary", "--data", "no/such/folder"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no/such/folder"), "{err}");

    let out = rtr(&["render", "--width", "0", "--out", "unused.png"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--width") && err.contains("16..=20000"),
        "{err}"
    );

    let out = rtr(&["render", "--out", "scene.bmp"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains(".png or .svg"));

    let out = rtr(&["eval", "--idm", "--set", "nominal", "--a9-bend", "-0.05"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--a9-bend -0.05") && err.contains("0.01"),
        "{err}"
    );

    let out = rtr(&[
        "eval",
        "--idm",
        "--set",
        "longtail",
        "--generated-speed-limit",
        "0",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--generated-speed-limit 0") && err.contains("km/h"),
        "{err}"
    );
    let out = rtr(&[
        "eval",
        "--idm",
        "--set",
        "nominal",
        "--generated-speed-limit",
        "100",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("add longtail or ood"),
        "{err}"
    );
}

#[test]
fn procedural_maps_render_and_export_to_opendrive_that_reads_back() {
    let dir = tempfile::tempdir().expect("temp dir");
    let xodr = dir.path().join("merge.xodr");
    let out = rtr(&[
        "map",
        "export",
        "--procedural",
        "on_ramp_merge",
        "--out",
        xodr.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = rtr(&["map", "summary", "--xodr", xodr.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert!(v["junctions"].as_u64().unwrap() >= 1, "{v}");
    assert!(v["driving_lanes"].as_u64().unwrap() >= 3, "{v}");

    let png = dir.path().join("fork.png");
    let out = rtr(&[
        "map",
        "render",
        "--procedural",
        "off_ramp_fork",
        "--width",
        "600",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A real drawing: the width asked for, and more than one colour (road on ground).
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&png).expect("png"),
    ));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut pixels = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut pixels).expect("a frame");
    assert_eq!(info.width, 600);
    let first = &pixels[..3];
    assert!(pixels.chunks(3).any(|p| p != first), "one flat colour");

    let out = rtr(&[
        "map",
        "summary",
        "--procedural",
        "{\"kind\":\"lane_drop\",\"lanes\":0}",
    ]);
    assert!(!out.status.success());
    let out = rtr(&["map", "summary", "--procedural", "roundabout"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected one of"));
}

#[test]
fn bench_sim_prints_its_figures_and_names_missing_backends() {
    let out = rtr(&["bench", "sim", "--json", "--repetitions", "1"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert!(v["agent_steps_per_s"].as_f64().unwrap() > 0.0, "{v}");
    assert!(v["rollout_grad_ms"].as_f64().unwrap() > 0.0, "{v}");
    assert_eq!(v["step_batch"], serde_json::json!([64, 50]));

    let out = rtr(&["bench", "sim", "--backend", "vulkan9"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected ndarray, flex or wgpu"));
    if !cfg!(feature = "wgpu") {
        let out = rtr(&["bench", "sim", "--backend", "wgpu"]);
        assert!(!out.status.success());
        assert!(String::from_utf8_lossy(&out.stderr).contains("--features wgpu"));
    }
    for bench in ["model", "train"] {
        let out = rtr(&["bench", bench, "--devices", "0"]);
        assert!(!out.status.success());
        assert!(
            String::from_utf8_lossy(&out.stderr).contains("'0' for '--devices"),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // Sizes given as flags are refused as the flags, not as run-file fields.
    let out = rtr(&[
        "bench",
        "train",
        "--small",
        "--ppo-batch",
        "8",
        "--ppo-minibatch",
        "16",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("--ppo-minibatch: expected a divisor of --ppo-batch (8)")
            && !err.contains("field"),
        "{err}"
    );
}

#[test]
fn model_info_counts_parameters_and_rejects_bad_configs() {
    let out = rtr(&["model", "info", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(report["config"]["hidden"], 128);
    let policy = report["policy"]["total"].as_u64().expect("policy total");
    let value = report["value"]["total"].as_u64().expect("value total");
    assert_eq!(report["params"].as_u64(), Some(policy + value));
    assert!(
        policy > 1_000_000,
        "paper-size policy has {policy} parameters"
    );

    let text = rtr(&["model", "info", "--small"]);
    assert!(text.status.success());
    assert!(String::from_utf8_lossy(&text.stdout).contains("policy + value"));

    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("model.toml");
    std::fs::write(&path, "hidden = 64\nhistory_kernel = 2\n").expect("write");
    let bad = rtr(&[
        "model",
        "info",
        "--config",
        path.to_str().expect("utf-8 path"),
    ]);
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("model.toml") && err.contains("history_kernel"),
        "{err}"
    );
    std::fs::write(&path, "hidden = \"wide\"\n").expect("write");
    let bad = rtr(&[
        "model",
        "info",
        "--config",
        path.to_str().expect("utf-8 path"),
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("line 1"), "{err}");
    // A run file gives its [model] table; a mistake in it is found at its line.
    let run = rtr(&[
        "model",
        "info",
        "--config",
        "experiments/main/rtr.toml",
        "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).expect("JSON");
    assert_eq!(report["config"]["hidden"], 64);
    std::fs::write(
        &path,
        "method = \"IL\"\n[model]\nhidden = 32.5\n[imitation]\nagent_dropout = 0.5\n",
    )
    .expect("write");
    let bad = rtr(&["model", "info", "--config", path.to_str().expect("utf-8")]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("line 3") && err.contains("hidden"),
        "{err}"
    );
    // A value out of range is found at its line too, in a run file or a model config.
    for (text, line) in [
        ("method = \"IL\"\n[model]\nhidden = 0\n", "line 3"),
        ("hidden = 100000\n", "line 1"),
    ] {
        std::fs::write(&path, text).expect("write");
        let bad = rtr(&["model", "info", "--config", path.to_str().expect("utf-8")]);
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains(line) && err.contains("hidden"),
            "{err}"
        );
    }
    // A `[model]` table copied out of a run file is read as the model; a typo in it is named.
    std::fs::write(&path, "[model]\nhidden = 8\n").expect("write");
    let table = rtr(&[
        "model",
        "info",
        "--config",
        path.to_str().expect("utf-8"),
        "--json",
    ]);
    let report: serde_json::Value = serde_json::from_slice(&table.stdout).expect("JSON");
    assert_eq!(report["config"]["hidden"], 8);
    std::fs::write(&path, "[model]\nhiden = 8\n").expect("write");
    let bad = rtr(&["model", "info", "--config", path.to_str().expect("utf-8")]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("line 2") && err.contains("unknown field `hiden`"),
        "{err}"
    );
}

#[test]
fn train_names_the_bad_run_file_and_the_missing_reference() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "method = \"RTR\"\n[ppo]\nclip = 1.5\n").expect("write");
    let out = rtr(&["train", "--config", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.toml") && err.contains("ppo.clip"),
        "{err}"
    );

    let kl = dir.path().join("kl.toml");
    std::fs::write(
        &kl,
        "method = \"KL-L\"\n[reference]\ncheckpoint = \"nowhere/il.bpk\"\n",
    )
    .expect("write");
    let out = rtr(&[
        "train",
        "--config",
        kl.to_str().unwrap(),
        "--out",
        dir.path().join("run").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("nowhere/il.bpk"),
        "{err}"
    );
    // A file the run would refuse for its size is refused by its field before any data loads
    // (the data folder does not exist).
    let huge = dir.path().join("huge.txt");
    std::fs::File::create(&huge)
        .and_then(|f| f.set_len(65 * 1024 * 1024))
        .expect("a sparse file");
    let run_file = dir.path().join("curated.toml");
    std::fs::write(
        &run_file,
        format!(
            "method = \"IL\"\n[data]\ncurated = {:?}\n",
            huge.to_str().unwrap()
        ),
    )
    .expect("write");
    let out = rtr(&[
        "train",
        "--config",
        run_file.to_str().unwrap(),
        "--data",
        "/nonexistent",
        "--out",
        dir.path().join("run").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("field `data.curated`") && err.contains("64 MiB"),
        "{err}"
    );
}

#[test]
fn sim2real_writes_the_documented_report_dynamics_and_plots_as_one_set() {
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("rec.csv");
    let results = dir.path().join("results");
    let report = results.join("report.json");
    let dynamics = results.join("dynamics.toml");
    let path = |p: &std::path::Path| p.to_str().expect("utf-8 path").to_string();
    let out = rtr(&[
        "recordings",
        "generate",
        "--effect",
        "accel_lag",
        "--tracks",
        "6",
        "--out",
        &path(&csv),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = rtr(&[
        "sim2real",
        "--recordings",
        &path(&csv),
        "--out",
        &path(&results),
        "--iterations",
        "40",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("JSON");
    assert!(
        v["baseline"]["heldout_pos_rmse_m"]
            .as_f64()
            .expect("baseline")
            > 0.0
    );
    assert!(v["final"]["heldout_pos_rmse_m"].as_f64().expect("final") > 0.0);
    assert!(v["mismatch"]["regimes"].as_array().expect("regimes").len() == 5);
    // The report names the contents it fitted, not only the path.
    let fitted = std::fs::read(&csv).expect("recordings");
    assert_eq!(
        v["source_sha256"].as_str(),
        Some(rtr::data::automatum::sha256_hex(&fitted).as_str())
    );
    let findings = v["findings"].as_array().expect("findings");
    assert_eq!(findings[0]["effect"], "accel_lag", "{v}");
    for key in ["params", "heldout_pos_rmse_m", "improvement_pct"] {
        assert!(!findings[0][key].is_null(), "{key} missing");
    }
    for plot in ["regimes.svg", "excess.svg", "hypotheses.svg", "tracks.svg"] {
        let svg = std::fs::read_to_string(results.join(plot)).expect("plot written");
        assert!(svg.contains("<svg"));
    }
    assert!(
        std::fs::read_to_string(&dynamics)
            .expect("dynamics")
            .contains("accel_lag")
    );
    // The record of the set lists every file written, so the next run replaces all of them.
    let record = std::fs::read_to_string(results.join(".rtr-output")).expect("record");
    assert!(record.starts_with("# rtr sim2real"), "{record}");
    for file in ["report.json", "dynamics.toml", "tracks.svg"] {
        assert!(record.lines().any(|l| l == file), "{record}");
    }
}

#[test]
fn sim2real_names_the_line_of_a_bad_recording() {
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("bad.csv");
    std::fs::write(
        &csv,
        "track_id,t,x,y,heading,speed,accel_cmd,steer_cmd\n1,0,0,0,0,10,0,0\n1,0.1,1,0,90,10,0,0\n",
    )
    .expect("written");
    let out = rtr(&[
        "sim2real",
        "--recordings",
        csv.to_str().expect("utf-8"),
        "--out",
        dir.path().join("r").to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 3") && err.contains("heading"), "{err}");
    assert!(!dir.path().join("r").exists());
}

#[test]
fn eval_prints_the_table_row_and_writes_the_documented_json() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run_file = tiny_run_file(dir.path(), 1, "");
    let run = dir.path().join("run");
    let trained = rtr(&[
        "train",
        "--config",
        run_file.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
    ]);
    assert!(
        trained.status.success(),
        "{}",
        String::from_utf8_lossy(&trained.stderr)
    );
    let eval_into = |out: &std::path::Path| {
        rtr(&[
            "eval",
            "--checkpoint",
            run.to_str().unwrap(),
            "--set",
            "nominal",
            "--resamples",
            "100",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let out_dir = dir.path().join("eval");
    let out = eval_into(&out_dir);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let row = stdout
        .lines()
        .find(|l| l.starts_with("| IL |"))
        .expect("an IL row");
    // Method + 11 nominal metrics + the realism score.
    assert_eq!(row.matches('|').count(), 14, "{row}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("results.json")).expect("results.json"))
            .expect("JSON");
    let nominal = &json["methods"]["IL"]["nominal"];
    for key in [
        "collision_pct",
        "offroad_pct",
        "infraction_pct",
        "hit_by_log_pct",
        "fde_m",
        "ate_m",
        "cte_m",
        "jsd_acc",
        "jsd_speed",
        "jsd_lat",
        "jsd_lead",
    ] {
        assert!(nominal[key].is_number(), "{key}: {nominal}");
        assert!(nominal[format!("{key}_ci")].is_number(), "{key}_ci");
    }
    assert_eq!(nominal["scenes"], 100);
    // Either infraction: at least each one alone, at most both together.
    let pct = |key: &str| nominal[key].as_f64().expect(key);
    let any = pct("infraction_pct");
    assert!(
        any >= pct("collision_pct").max(pct("offroad_pct")),
        "{nominal}"
    );
    assert!(
        any <= pct("collision_pct") + pct("offroad_pct") + 1e-9,
        "{nominal}"
    );
    let realism = nominal["realism"].as_f64().expect("realism");
    assert!(realism > 0.0 && realism <= 1.0, "{realism}");
    for file in [
        "table.md",
        "figures/histograms_il.svg",
        "figures/training_curves.svg",
    ] {
        assert!(out_dir.join(file).is_file(), "{file} missing");
    }
    // A study that cannot be written whole writes nothing: its `figures` is taken by a file.
    let blocked = dir.path().join("blocked");
    std::fs::create_dir(&blocked).expect("mkdir");
    std::fs::write(blocked.join("figures"), "x").expect("write");
    let out = eval_into(&blocked);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("figures"), "{err}");
    assert_eq!(entries(&blocked), ["figures"], "nothing else was written");
    assert!(!entries(dir.path()).iter().any(|n| n.contains("staging")));
    // Weights changed after training are not evaluated as the trained ones.
    let policy = run.join("policy.bpk");
    let mut bytes = std::fs::read(&policy).expect("policy");
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&policy, bytes).expect("write");
    let out = eval_into(&dir.path().join("tampered"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("sha256")
            && err.contains("changed or corrupted since"),
        "{err}"
    );
}

/// The names in `dir`, sorted.
fn entries(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn eval_names_what_is_wrong_with_its_arguments() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = rtr(&["eval", "--checkpoint", dir.path().to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no policy.bpk"),
        "{err}"
    );
    let out = rtr(&["eval", "--idm", "--set", "nominal,highway"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("unknown scene set `highway`"),
        "{err}"
    );
    let out = rtr(&["eval"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--checkpoint"),
        "{err}"
    );
}

/// Every count a user gives is bounded where it is parsed, before any work: zero resamples
/// (every interval +- 0), a zero batch, billions of tracks (a 320 GB allocation) and zero
/// iterations are refused, naming the flag and the accepted range.
#[test]
fn counts_out_of_range_are_refused_naming_the_flag() {
    let dir = tempfile::tempdir().expect("temp dir");
    let csv = dir.path().join("r.csv");
    let csv_path = csv.to_str().unwrap();
    let cases: [(&str, &[&str]); 7] = [
        ("--resamples", &["eval", "--idm", "--resamples", "0"]),
        ("--batch", &["eval", "--idm", "--batch", "0"]),
        (
            "--batch",
            &[
                "curate",
                "--checkpoint",
                "models/il",
                "--out",
                "x.txt",
                "--batch",
                "0",
            ],
        ),
        (
            "--tracks",
            &[
                "recordings",
                "generate",
                "--effect",
                "none",
                "--tracks",
                "4000000000",
                "--out",
                csv_path,
            ],
        ),
        (
            "--iterations",
            &["sim2real", "--a9", "--out", "unused", "--iterations", "0"],
        ),
        (
            "--resamples",
            &["sweep", "--config", "x.toml", "--resamples", "10"],
        ),
        (
            "--ood",
            &[
                "scenarios",
                "generate",
                "--out",
                "unused",
                "--ood",
                "1000000",
            ],
        ),
    ];
    for (flag, args) in cases {
        let out = rtr(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(flag) && err.contains("is not in"),
            "{args:?}: {err}"
        );
    }
    assert!(!csv.exists(), "nothing written on error");
    let out = rtr(&["sim2real", "--a9", "--out", "unused", "--horizon", "0.05"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("0.05 s horizon") && !err.contains("panicked"),
        "{err}"
    );
    let out = rtr(&[
        "sim2real",
        "--a9",
        "--out",
        "unused",
        "--command-timing",
        "zoh",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--command-timing `zoh`") && err.contains("auto"),
        "{err}"
    );
    let out = rtr(&[
        "scenarios",
        "generate",
        "--out",
        "unused",
        "--in-distribution",
        "0",
        "--ood",
        "0",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("nothing to generate"),
        "{err}"
    );
    assert!(!std::path::Path::new("unused").exists());
}

#[test]
fn curate_and_downstream_name_what_is_wrong() {
    let dir = tempfile::tempdir().expect("temp dir");
    let list = dir.path().join("curated.txt");
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).expect("mkdir");
    let out = rtr(&[
        "curate",
        "--checkpoint",
        empty.to_str().unwrap(),
        "--out",
        list.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no policy.bpk"),
        "{err}"
    );
    assert!(!list.exists(), "nothing written on error");
    let out = rtr(&["downstream", "--idm", "--seeds", "0"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--seeds"), "{err}");
    let out = rtr(&["downstream", "--idm", "--epochs", "0"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--epochs"), "{err}");
    let out = rtr(&["downstream", "--checkpoint", dir.path().to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("no policy.bpk"),
        "{err}"
    );
}

/// An output that cannot be written is refused before any work (eval once ran 35 s, curate
/// 17 s and sim2real a whole identification first), naming the flag, and nothing is written:
/// a file where a folder is needed, a folder where a file is needed, a path under a file.
#[test]
fn unwritable_outputs_are_refused_before_any_work() {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").expect("write");
    let under_file = file.join("report.json");
    let folder = dir.path().to_str().unwrap();
    let cases: [(&str, Vec<&str>); 9] = [
        (
            "--out",
            vec!["eval", "--idm", "--out", file.to_str().unwrap()],
        ),
        (
            "--out",
            vec!["curate", "--checkpoint", "models/il", "--out", folder],
        ),
        (
            "--out",
            vec!["sim2real", "--a9", "--out", under_file.to_str().unwrap()],
        ),
        (
            "--out",
            vec!["sim2real", "--a9", "--out", file.to_str().unwrap()],
        ),
        (
            "--out",
            vec![
                "recordings",
                "generate",
                "--effect",
                "none",
                "--out",
                under_file.to_str().unwrap(),
            ],
        ),
        (
            "--out",
            vec!["scenarios", "generate", "--out", file.to_str().unwrap()],
        ),
        (
            "--out",
            vec![
                "map",
                "export",
                "--procedural",
                "curve",
                "--out",
                under_file.to_str().unwrap(),
            ],
        ),
        (
            "--out",
            vec![
                "map",
                "render",
                "--procedural",
                "curve",
                "--out",
                under_file.to_str().unwrap(),
            ],
        ),
        (
            "--out",
            vec!["render", "--out", under_file.to_str().unwrap()],
        ),
    ];
    for (flag, args) in cases {
        let started = std::time::Instant::now();
        let out = rtr(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(flag),
            "{args:?}: {err}"
        );
        // Refused at once: no data loaded, nothing simulated.
        assert!(
            started.elapsed().as_secs_f64() < 5.0,
            "{args:?} took {:?}",
            started.elapsed()
        );
    }
    assert!(!std::path::Path::new("unused.json").exists());
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .expect("dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(names, ["a-file"], "nothing else was written");
}

/// `scenarios generate` into a folder whose set folders hold files it did not write refuses
/// before drawing (the loaders read every file of a set folder, so they would join the new
/// set); its own earlier set there is replaced whole, no scenario of it left behind.
#[test]
fn scenarios_replace_their_own_earlier_set_and_nothing_else() {
    let dir = tempfile::tempdir().expect("temp dir");
    let generate = |count: &str| {
        rtr(&[
            "scenarios",
            "generate",
            "--in-distribution",
            count,
            "--ood",
            "0",
            "--out",
            dir.path().to_str().unwrap(),
        ])
    };
    let files = |set: &str| {
        std::fs::read_dir(dir.path().join(set))
            .map(|entries| entries.count())
            .unwrap_or(0)
    };
    let out = generate("6");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!((files("train"), files("eval")), (3, 3));
    let out = generate("2");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        (files("train"), files("eval")),
        (1, 1),
        "the earlier set is gone"
    );

    let stale = dir.path().join("train").join("stale.json");
    std::fs::write(&stale, "{}").expect("write");
    let out = generate("4");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("did not write") && err.contains("train"),
        "{err}"
    );
    assert_eq!((files("train"), files("eval")), (2, 1), "nothing written");
}

/// Inputs that are not what their flag wants are refused naming the flag: a folder given as
/// a file, a scenario folder without its train/ set, a missing curated list of a run file.
#[test]
fn misplaced_inputs_name_their_flag_or_field() {
    let dir = tempfile::tempdir().expect("temp dir");
    let folder = dir.path().to_str().unwrap();
    let cases: [(&str, Vec<&str>); 4] = [
        ("--xodr", vec!["map", "summary", "--xodr", folder]),
        ("--config", vec!["train", "--config", folder]),
        (
            "--recordings",
            vec!["sim2real", "--recordings", folder, "--out", "unused"],
        ),
        (
            "--scenarios",
            vec![
                "train",
                "--config",
                "experiments/main/small/rtr.toml",
                "--scenarios",
                folder,
            ],
        ),
    ];
    for (flag, args) in cases {
        let out = rtr(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(flag) && err.contains(folder),
            "{args:?}: {err}"
        );
    }
    let run = dir.path().join("run.toml");
    std::fs::write(
        &run,
        "method = \"RTR\"\nalpha = 0.5\n[data]\ncurated = \"missing.txt\"\nnominal_limit = 2\n",
    )
    .expect("write");
    let out = rtr(&[
        "train",
        "--config",
        run.to_str().unwrap(),
        "--out",
        dir.path().join("out").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("data.curated") && err.contains("missing.txt"),
        "{err}"
    );
    // Every path a run file names is checked before the data loads.
    for (field, line) in [
        ("dynamics", "dynamics = \"no_dynamics.toml\""),
        ("init.policy", "[init]\npolicy = \"no_model\""),
    ] {
        std::fs::write(&run, format!("method = \"IL\"\n{line}\n")).expect("write");
        let out = rtr(&[
            "train",
            "--config",
            run.to_str().unwrap(),
            "--out",
            dir.path().join("out").to_str().unwrap(),
            "--data",
            dir.path().join("no_data").to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(&format!("field `{field}`")),
            "{field}: {err}"
        );
    }
}

/// A fresh run refused after its data loaded (here a dynamics file that is not one) leaves
/// no run folder behind: nothing for a later `--resume` to trip over.
#[test]
fn a_refused_training_run_leaves_no_folder() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = dir.path().join("run");
    let missing = dir.path().join("nope_dynamics.toml");
    std::fs::write(&missing, "[[terms]]\neffect = \"no_such_effect\"\n").expect("write");
    let out = rtr(&[
        "train",
        "--config",
        "experiments/main/small/il.toml",
        "--dynamics",
        missing.to_str().unwrap(),
        "--out",
        run.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("nope_dynamics.toml"),
        "{err}"
    );
    assert!(!run.exists(), "the run folder was left behind");
}

#[test]
fn model_average_writes_a_loadable_policy_and_refuses_mixed_runs() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("mean");
    let il = "models/il";
    let average = |checkpoints: &[&str], out: &std::path::Path| {
        let mut args = vec!["model", "average"];
        for c in checkpoints {
            args.extend(["--checkpoint", c]);
        }
        args.extend(["--out", out.to_str().expect("utf-8 path")]);
        let output = rtr(&args);
        (
            output.status.success(),
            String::from_utf8_lossy(&output.stderr).to_string(),
        )
    };
    // One policy twice would pass for an average of two.
    let (ok, err) = average(&[il, il], &out);
    assert!(
        !ok && err.contains("same weights") && !out.exists(),
        "{err}"
    );
    // A second policy of the same config and method (freshly initialised weights).
    let device = rtr::backend::Backend::NdArray
        .device(false)
        .expect("CPU device");
    let config = std::fs::read_to_string(format!("{il}/config.toml")).expect("config");
    let second = dir.path().join("second");
    std::fs::create_dir(&second).expect("folder");
    std::fs::write(second.join("config.toml"), &config).expect("config written");
    let model = rtr::eval::trained::TrainedPolicy::load(std::path::Path::new(il), &device)
        .expect("loads")
        .config
        .model;
    let fresh = rtr::model::PolicyNetwork::new(&model, &device);
    std::fs::write(second.join("policy.bpk"), policy_bytes(fresh)).expect("policy written");
    let second_arg = second.to_str().expect("utf-8 path").to_string();
    let (ok, err) = average(&[il, &second_arg], &out);
    assert!(ok, "{err}");
    let mean = rtr::eval::trained::TrainedPolicy::load(&out, &device).expect("average loads");
    assert_eq!(mean.method, "IL");
    let read = |p: &std::path::Path| std::fs::read(p).expect("policy file");
    let averaged = read(&out.join("policy.bpk"));
    assert_ne!(averaged, read(&std::path::Path::new(il).join("policy.bpk")));
    assert_ne!(averaged, read(&second.join("policy.bpk")));
    let sources: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("averaged.json")).expect("averaged.json"))
            .expect("JSON");
    assert_eq!(sources["sources"].as_array().map(Vec::len), Some(2));
    // The average records its own weights, so a changed copy is refused where it loads.
    assert_eq!(
        sources["policy_sha256"].as_str(),
        Some(rtr::data::automatum::sha256_hex(&averaged).as_str())
    );

    // Run again, it replaces its own earlier average; a model folder is never replaced.
    let (ok, err) = average(&[il, &second_arg], &out);
    assert!(ok, "{err}");
    assert_eq!(read(&out.join("policy.bpk")), averaged);
    let a_model = dir.path().join("a_model");
    std::fs::create_dir(&a_model).expect("folder");
    std::fs::write(a_model.join("policy.bpk"), b"weights").expect("policy written");
    let (ok, err) = average(&[il, &second_arg], &a_model);
    assert!(!ok && err.contains("a model or a training run"), "{err}");
    assert_eq!(read(&a_model.join("policy.bpk")), b"weights");
    let other = dir.path().join("mixed");
    let (ok, err) = average(&[il, "models/rtr"], &other);
    assert!(!ok && err.contains("one run") && !other.exists(), "{err}");
    let (ok, err) = average(&[il], &other);
    assert!(!ok && err.contains("at least two"), "{err}");
    // Another seed of the same run file is another run.
    let reseeded = dir.path().join("reseeded");
    std::fs::create_dir(&reseeded).expect("folder");
    std::fs::write(reseeded.join("config.toml"), with_seed(&config, 12345)).expect("config");
    std::fs::copy(second.join("policy.bpk"), reseeded.join("policy.bpk")).expect("policy");
    let reseeded = reseeded.to_str().expect("utf-8 path");
    let (ok, err) = average(&[il, reseeded], &other);
    assert!(!ok && err.contains("seed") && !other.exists(), "{err}");

    // A run whose dynamics file sits beside its config: the averaged folder, elsewhere, still
    // finds it.
    let run = dir.path().join("run");
    std::fs::create_dir(&run).expect("run folder");
    std::fs::copy(second.join("policy.bpk"), run.join("policy.bpk")).expect("policy");
    std::fs::write(
        run.join("config.toml"),
        format!("dynamics = \"dynamics.toml\"\n{config}"),
    )
    .expect("config written");
    std::fs::write(
        run.join("dynamics.toml"),
        "[[terms]]\neffect = \"accel_lag\"\nparams = { tau_s = 0.8 }\n",
    )
    .expect("dynamics written");
    // A second policy of that run (the same run file and dynamics, in its own folder).
    let run_b = dir.path().join("run_b");
    std::fs::create_dir(&run_b).expect("run folder");
    for file in ["config.toml", "dynamics.toml"] {
        std::fs::copy(run.join(file), run_b.join(file)).expect("copy");
    }
    std::fs::copy(format!("{il}/policy.bpk"), run_b.join("policy.bpk")).expect("policy");
    let (run, run_b) = (
        run.to_str().expect("utf-8 path"),
        run_b.to_str().expect("utf-8 path"),
    );
    // A run with a dynamics file is not a checkpoint of one without.
    let (ok, err) = average(&[run, il], &other);
    assert!(!ok && err.contains("dynamics"), "{err}");
    let moved = dir.path().join("elsewhere").join("mean");
    let (ok, err) = average(&[run, run_b], &moved);
    assert!(ok, "{err}");
    let loaded = rtr::eval::trained::TrainedPolicy::load(&moved, &device).expect("loads");
    assert!(loaded.config.dynamics.is_some());
}

/// A run file's text with its top-level `seed` set to `seed`.
fn with_seed(config: &str, seed: u64) -> String {
    let mut table: toml::Table = config.parse().expect("TOML run file");
    table.insert("seed".into(), toml::Value::Integer(seed as i64));
    toml::to_string(&table).expect("TOML")
}

/// A policy network's parameters as the bytes of a `policy.bpk`.
fn policy_bytes(network: rtr::model::PolicyNetwork) -> Vec<u8> {
    use burn::module::Module;
    network
        .into_record()
        .into_bytes()
        .expect("parameters serialise")
        .to_vec()
}

/// A probe has no `--resume`: an earlier probe's run in a task's folder is refused by the
/// `--out` flag, before the task trains, not with the trainer's advice to pass `--resume`.
#[test]
fn a_probe_into_an_earlier_probe_run_is_refused_by_its_out_folder() {
    let dir = tempfile::tempdir().expect("temp dir");
    let checkpoints = dir.path().join("brake").join("checkpoints");
    std::fs::create_dir_all(&checkpoints).expect("folders");
    std::fs::write(checkpoints.join("latest"), "iter-000001\n").expect("pointer");
    let out = rtr(&[
        "probe",
        "ppo",
        "--small",
        "--tasks",
        "brake",
        "--iterations",
        "1",
        "--out",
        dir.path().to_str().expect("utf-8 path"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("--out")
            && err.contains("probe run of `brake`")
            && !err.contains("--resume"),
        "{err}"
    );
}

/// A checkpoint that cannot be written (a full disk: the file size limit) stops the run with
/// the error, leaves the newest good checkpoint, and takes the curve rows of the lost
/// iterations back out: `curves.csv` matches the checkpoint there is.
#[test]
fn a_checkpoint_that_cannot_be_written_leaves_curves_that_match_the_last_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run_file = tiny_run_file(dir.path(), 3, "");
    let run = dir.path().join("run");
    let (config, out) = (run_file.to_str().unwrap(), run.to_str().unwrap());
    let first = rtr(&[
        "train",
        "--config",
        config,
        "--out",
        out,
        "--stop-after",
        "1",
    ]);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let rows_before = std::fs::read_to_string(run.join("curves.csv")).expect("curves");
    // Files of at most 4 KiB: a curves row fits, a checkpoint's networks do not.
    let full = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f 8; exec {} train --config {config} --out {out} --resume \
             --stop-after 1",
            env!("CARGO_BIN_EXE_rtr")
        ))
        .output()
        .expect("bash runs");
    let err = String::from_utf8_lossy(&full.stderr);
    assert!(
        !full.status.success() && err.contains("File too large"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(run.join("checkpoints/latest")).expect("latest"),
        "iter-000001"
    );
    assert_eq!(
        std::fs::read_to_string(run.join("curves.csv")).expect("curves"),
        rows_before,
        "the rows of the lost iteration are gone again"
    );
    let resumed = rtr(&["train", "--config", config, "--out", out, "--resume"]);
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
}

/// Two trainings of one run file are two runs: their checkpoints share no basin, and their
/// weight average is refused, naming the two runs.
#[test]
fn model_average_refuses_two_trainings_of_one_run_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run_file = tiny_run_file(dir.path(), 2, "[run]\nkeep_checkpoints = 2\n");
    let config = run_file.to_str().unwrap();
    let runs = ["a", "b"].map(|name| dir.path().join(name));
    for run in &runs {
        let out = rtr(&["train", "--config", config, "--out", run.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let checkpoint = |run: &std::path::Path, k: usize| {
        run.join(format!("checkpoints/iter-{k:06}"))
            .to_str()
            .unwrap()
            .to_string()
    };
    let (a1, a2, b2) = (
        checkpoint(&runs[0], 1),
        checkpoint(&runs[0], 2),
        checkpoint(&runs[1], 2),
    );
    let mean = dir.path().join("mean");
    let average = |x: &str, y: &str| {
        rtr(&[
            "model",
            "average",
            "--checkpoint",
            x,
            "--checkpoint",
            y,
            "--out",
            mean.to_str().unwrap(),
        ])
    };
    let out = average(&a1, &b2);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("two trainings of it"),
        "{err}"
    );
    let out = average(&a1, &a2);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A run file of a few seconds' IL training on the tiny network, `epochs` long, with `extra`
/// appended, written as `dir/tiny.toml`.
fn tiny_run_file(dir: &std::path::Path, epochs: usize, extra: &str) -> std::path::PathBuf {
    let path = dir.join("tiny.toml");
    std::fs::write(
        &path,
        format!(
            "method = \"IL\"\nseed = 3\n[optimizer]\nlearning_rate = 1e-3\nepochs = {epochs}\n\
             epoch_scenes = 2\n[imitation]\nminibatch = 2\n[data]\nnominal_limit = 4\n\
             max_rollout_steps = 4\n[model]\nhidden = 16\nlane_layers = 1\n\
             interaction_rounds = 1\nhistory_blocks = 1\nhead_hidden = [16]\n{extra}"
        ),
    )
    .expect("write");
    path
}
