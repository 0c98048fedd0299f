//! One interface over both segmentation pipelines, selected by the scenario's
//! `method.segmentation`, with the settings each pipeline is recommended to run at.

use crate::adaptive_background::{AdaptiveBackground, AdaptiveBackgroundParams};
use crate::colour_difference::{ColourDifference, ColourDifferenceParams, HsiClass};
use proto::scenario::{Scenario, Segmentation};
use proto::sensor::Detection;
use proto::sensor::{Frame, FrameError};

/// Both pipelines' parameters; only the selected one is used.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct SegmentParams {
    pub kind: Segmentation,
    pub colour_difference: ColourDifferenceParams,
    pub adaptive_background: AdaptiveBackgroundParams,
}

/// Recommended processing step for a frame width: about 320 grid pixels across, at most 3.
/// 352×288 runs at full resolution, 640×480 on every second pixel, 1920×1080 on every third.
pub fn recommended_step(width: u32) -> u32 {
    (width / 320).clamp(1, 3)
}

impl SegmentParams {
    /// The scenario's pipeline at the recommended step for `width`; paper 000's colour classes
    /// are the scenario's `method.target-colours` (its §6.1.1 assumes the colour is known).
    pub fn for_scenario(scenario: &Scenario, width: u32) -> SegmentParams {
        let step = recommended_step(width);
        SegmentParams {
            kind: scenario.method.segmentation,
            colour_difference: ColourDifferenceParams {
                classes: scenario
                    .method
                    .target_colours
                    .iter()
                    .map(|&rgb| HsiClass::around_rgb(rgb))
                    .collect(),
                step,
                min_pixels: (48 / (step * step)).max(4),
                ..ColourDifferenceParams::default()
            },
            adaptive_background: AdaptiveBackgroundParams {
                step,
                min_pixels: (48 / (step * step)).max(4),
                ..AdaptiveBackgroundParams::default()
            },
        }
    }
}

/// The selected pipeline. Both boxed: their bookkeeping differs by hundreds of bytes, and a
/// camera holds one.
#[derive(Debug)]
pub enum Segmenter {
    ColourDifference(Box<ColourDifference>),
    AdaptiveBackground(Box<AdaptiveBackground>),
}

impl Segmenter {
    pub fn new(params: &SegmentParams) -> Segmenter {
        match params.kind {
            Segmentation::ColourDifference => {
                Segmenter::ColourDifference(Box::new(ColourDifference::new(params.colour_difference.clone())))
            }
            Segmentation::AdaptiveBackground => Segmenter::AdaptiveBackground(Box::new(
                AdaptiveBackground::new(params.adaptive_background.clone()),
            )),
        }
    }

    pub fn kind(&self) -> Segmentation {
        match self {
            Segmenter::ColourDifference(_) => Segmentation::ColourDifference,
            Segmenter::AdaptiveBackground(_) => Segmentation::AdaptiveBackground,
        }
    }

    /// Regions the background model dropped as ghosts so far ([`crate::ghost`]; none for
    /// colour difference, which has no model to leave them).
    pub fn ghosts(&self) -> u64 {
        match self {
            Segmenter::ColourDifference(_) => 0,
            Segmenter::AdaptiveBackground(s) => s.ghosts(),
        }
    }

    /// Moving pixels the background model took back as the colour it had settled on
    /// (`adaptive_background::settled`; none for colour difference).
    pub fn revealed_pixels(&self) -> u64 {
        match self {
            Segmenter::ColourDifference(_) => 0,
            Segmenter::AdaptiveBackground(s) => s.revealed(),
        }
    }

    /// Segment a frame into `out` (cleared first).
    ///
    /// # Errors
    /// A malformed frame or one of another size than the first; no state changes then.
    pub fn process(&mut self, frame: &Frame, out: &mut Vec<Detection>) -> Result<(), FrameError> {
        match self {
            Segmenter::ColourDifference(s) => s.process(frame, out),
            Segmenter::AdaptiveBackground(s) => s.process(frame, out),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recommended_steps() {
        assert_eq!(recommended_step(352), 1);
        assert_eq!(recommended_step(640), 2);
        assert_eq!(recommended_step(1920), 3);
        let s = Scenario::default_scenario();
        let p = SegmentParams::for_scenario(&s, 352);
        assert_eq!(p.kind, Segmentation::AdaptiveBackground);
        assert_eq!(p.colour_difference.classes.len(), s.method.target_colours.len());
        assert_eq!(Segmenter::new(&p).kind(), Segmentation::AdaptiveBackground);
    }
}
