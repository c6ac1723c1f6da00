//! `rtr map`: describe, draw or export an OpenDRIVE or procedural map.

use std::path::PathBuf;

use clap::Subcommand;

use rtr::data::a9;
use rtr::io::claim_output_file;
use rtr::map::{LaneGraph, to_xodr};
use rtr::render::{RenderOptions, render_map};
use rtr::{Error, Result};

use super::args::{MapSource, image_targets, image_width};

#[derive(Subcommand)]
pub enum MapCommand {
    /// Road length, lanes and lane-graph size as JSON.
    Summary(MapSource),
    /// Draw the empty map to PNG/SVG.
    Render {
        #[command(flatten)]
        source: MapSource,
        /// Output file (.png or .svg), or a prefix without extension for both.
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 2400, value_parser = image_width())]
        width: u32,
    },
    /// Write the map as an OpenDRIVE file (procedural maps open in any OpenDRIVE viewer).
    Export {
        #[command(flatten)]
        source: MapSource,
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(command: MapCommand) -> Result<()> {
    match command {
        MapCommand::Summary(source) => {
            let map = source.load()?;
            let graph = LaneGraph::build(&map, a9::LANE_NODE_LENGTH);
            let summary = serde_json::json!({
                "source": map.source(),
                "roads": map.opendrive().map_or(0, |od| od.roads.len()),
                "junctions": map.opendrive().map_or(0, |od| od.junctions.len()),
                "road_length_m": map.road_length(),
                "driving_lanes": map.driving_lane_count(),
                "sampled_lanes": map.lanes().len(),
                "lane_graph_nodes": graph.nodes.len(),
                "bounds_m": map.bounds(),
            });
            rtr::outln!("{summary:#}")?;
            Ok(())
        }
        MapCommand::Render { source, out, width } => {
            let opts = RenderOptions {
                width_px: width,
                ..Default::default()
            };
            let (targets, _claims) = image_targets(&out, &opts, &source.inputs())?;
            let map = source.load()?;
            // Every file first, as one set: a full stdout must not cut the set short.
            render_map(&map, &targets, &opts)?;
            for path in &targets {
                rtr::outln!("wrote {}", path.display())?;
            }
            Ok(())
        }
        MapCommand::Export { source, out } => {
            let _claim =
                claim_output_file(&out, "--out", &source.inputs(), &rtr::map::OPENDRIVE_FILE)?;
            let map = source.load()?;
            let od = map.opendrive().ok_or_else(|| {
                Error::InvalidArgument(format!("{} is not an OpenDRIVE map", map.source()))
            })?;
            rtr::io::atomic_write(&out, to_xodr(od).as_bytes())?;
            rtr::outln!("wrote {}", out.display())?;
            Ok(())
        }
    }
}
