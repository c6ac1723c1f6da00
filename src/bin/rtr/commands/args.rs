//! Arguments and helpers shared by several subcommands: counts, the A9 data folder, map sources.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use rtr::backend::Backend;
use rtr::data::{A9Dataset, a9};
use rtr::io::{Inputs, OutputClaim, claim_output_file};
use rtr::map::{Map, ProceduralMap};
use rtr::render::{MAX_WIDTH_PX, RenderOptions, check_target, output_paths};
use rtr::{Error, Result};

/// A count flag within `min..=max`; clap's error names the flag, the value and the range.
pub fn count(min: u64, max: u64) -> impl clap::builder::TypedValueParser<Value = usize> {
    use clap::builder::TypedValueParser;
    clap::value_parser!(u64)
        .range(min..=max)
        .map(|v| usize::try_from(v).unwrap_or(usize::MAX))
}

#[derive(Args)]
pub struct DataArgs {
    /// Folder with the AUTOMATUM A9 files (default: the copy shipped in data/automatum-a9).
    #[arg(long)]
    pub data: Option<PathBuf>,
}

impl DataArgs {
    /// The A9 folder read: `--data` or the shipped copy.
    pub fn dir(&self) -> PathBuf {
        self.data.clone().unwrap_or_else(a9::default_dir)
    }

    /// The A9 folder read, checked to be a folder (`--data` named in the error).
    pub fn checked_dir(&self) -> Result<PathBuf> {
        if let Some(dir) = &self.data {
            rtr::io::check_input_folder(dir, "--data", "the AUTOMATUM A9 folder")?;
            for file in [a9::STATIC_FILE, a9::DYNAMIC_FILE] {
                if dir.join(file).symlink_metadata().is_err() {
                    return Err(rtr::Error::InvalidArgument(format!(
                        "--data {}: no {file} in it; expected the AUTOMATUM A9 folder ({} \
                         and {}, as shipped in data/automatum-a9)",
                        dir.display(),
                        a9::STATIC_FILE,
                        a9::DYNAMIC_FILE
                    )));
                }
            }
        }
        Ok(self.dir())
    }

    pub fn load(&self) -> Result<A9Dataset> {
        A9Dataset::load(&self.checked_dir()?)
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Split {
    Train,
    Test,
}

#[derive(Args)]
#[group(required = true, multiple = false)]
pub struct MapSource {
    /// An OpenDRIVE file.
    #[arg(long)]
    xodr: Option<PathBuf>,
    /// A generated map: a preset name (straight, curve, on_ramp_merge, off_ramp_fork,
    /// lane_drop) or a JSON object such as
    /// '{"kind":"lane_drop","lanes":3,"lane_width":3.75,"length":500,"drop_s":200,"taper_length":100}'.
    #[arg(long)]
    procedural: Option<String>,
}

impl MapSource {
    /// The file the map is read from, if any, for the output checks.
    pub fn inputs(&self) -> Inputs {
        Inputs::new().with_all("--xodr", &self.xodr)
    }

    pub fn load(&self) -> Result<Map> {
        match (&self.xodr, &self.procedural) {
            (Some(path), _) => {
                rtr::io::check_input_file(path, "--xodr")?;
                Map::from_xodr_file(path)
            }
            (None, Some(spec)) => {
                let od = self.procedural_spec(spec)?.build()?;
                Map::from_opendrive(&od, &format!("procedural:{spec}"))
            }
            (None, None) => Err(Error::InvalidArgument("give --xodr or --procedural".into())),
        }
    }

    fn procedural_spec(&self, spec: &str) -> Result<ProceduralMap> {
        if !spec.trim_start().starts_with('{') {
            return ProceduralMap::preset(spec);
        }
        let value: serde_json::Value = serde_json::from_str(spec)
            .map_err(|e| rtr::io::json_error("--procedural", Some(spec), &e))?;
        // A tagged enum's errors carry no position; name the field by comparing with the
        // preset of the same kind instead.
        serde_json::from_value(value.clone()).map_err(|e| {
            Error::invalid(
                "--procedural",
                mistyped_field(&value).map_or("JSON".into(), |f| format!("field `{f}`")),
                rtr::io::number_words(&e.to_string()),
            )
        })
    }
}

/// `--devices` (at least 1, checked by its parser), or the backend's default.
pub fn device_count(devices: Option<usize>, backend: Backend) -> Result<usize> {
    Ok(devices.unwrap_or_else(|| rtr::train::shards::default_devices(backend)))
}

/// The image files an `--out` names (itself if it has an extension, else PREFIX.png and
/// PREFIX.svg), each checked and claimed before any work: a .png or .svg name, writable, none
/// of `inputs`. The claims last as long as the returned values.
pub fn image_targets(
    out: &Path,
    opts: &RenderOptions,
    inputs: &Inputs,
) -> Result<(Vec<PathBuf>, Vec<OutputClaim>)> {
    let paths = match out.extension() {
        Some(_) => vec![out.to_path_buf()],
        None => output_paths(out).to_vec(),
    };
    let mut claims = Vec::new();
    for path in &paths {
        check_target(path, opts).map_err(|e| match e {
            Error::InvalidArgument(why) => Error::InvalidArgument(format!("--out {why}")),
            other => other,
        })?;
        claims.push(claim_output_file(
            path,
            "--out",
            inputs,
            &rtr::render::PICTURE,
        )?);
    }
    Ok((paths, claims))
}

/// `--width` of a picture, in pixels.
pub fn image_width() -> impl clap::builder::TypedValueParser<Value = u32> {
    clap::value_parser!(u32).range(16..=i64::from(MAX_WIDTH_PX))
}

/// The first field of a `--procedural` object whose JSON type differs from the same field of
/// the preset of its `kind` (a whole number where the preset has one, any number where it has
/// a number, an object where it has one).
fn mistyped_field(value: &serde_json::Value) -> Option<String> {
    let object = value.as_object()?;
    let Some(Ok(preset)) = object
        .get("kind")
        .and_then(|k| k.as_str())
        .map(ProceduralMap::preset)
    else {
        return Some("kind".into());
    };
    let preset = serde_json::to_value(preset).ok()?;
    object.iter().find_map(|(key, given)| {
        let fits = match preset.get(key) {
            Some(template) if template.is_u64() => given.is_u64(),
            Some(template) if template.is_number() => given.is_number(),
            Some(template) if template.is_object() => given.is_object(),
            Some(_) => true,
            // `layout` is optional in the presets that have one.
            None => key == "layout",
        };
        // A layout object of the right shape may still name an unknown layout type.
        let bad_layout =
            key == "layout" && serde_json::from_value::<rtr::map::Layout>(given.clone()).is_err();
        (!fits || bad_layout).then(|| key.clone())
    })
}
