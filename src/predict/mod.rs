//! The downstream task of paper section 4.2: a multimodal trajectory predictor trained on
//! data a traffic model simulated and scored on held-out real data.
//!
//! - [`sample`]: examples (an agent's context and its 5 s future) from real or simulated scenes;
//! - [`model`]: the predictor; [`fit`]: its training recipe; [`score`]: minFDE / minCTE.

pub mod fit;
pub mod model;
pub mod sample;
pub mod score;

pub use fit::{FitConfig, fit};
pub use model::{Predictor, PredictorConfig};
pub use sample::{PredictionSample, scene_samples};
pub use score::{PredictionScore, score};
