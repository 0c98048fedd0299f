//! Paper 004 (Fleck, Busch, Straßer 2007), the smart camera's claims in shape, at pixel level:
//! one camera of the default room (node 10) renders its frames with `world::render`, its
//! background model segments them, and either segmentation alone or the camera core's per-person
//! colour particle filters (`node_camera::ground_people`) report people on the ground plane.
//! Four studies, each a set of rows with shape checks that can fail:
//!
//! 1. **Partial occlusion** (§2, Fig. 6): a red person walks to and fro behind a narrow pillar
//!    that hides a vertical strip of them; tracked share of frames, image and ground error and
//!    identities per method, whole run and while the pillar hides their centre.
//! 2. **Self-adaptation** (§2.4, eq. 9): the same walk without the pillar under a slow global
//!    illumination change laid over the frames (dimming; dimming with a colour shift),
//!    histogram adaptation on (α = the scenario's default) vs off (α = 0).
//! 3. **Automatic initialisation and destruction** (§3.2.1): six people cross the view one
//!    after another, up to four at once; camera-level CLEAR MOT and IDF1 on the ground plane
//!    (`node_server::metrics`, 1 m threshold) against the truth in view. Also a stream of
//!    people, five or more in view at once for a good part of it (the bandwidth goal's case).
//! 4. **Bandwidth** (§3.2.4): bytes per second the camera puts on the wire for the crowd, and
//!    for the stream's frames with five or more in view, in each mode (ground observations as
//!    sent, and had every frame been sent; every filter's sample set every frame) against the
//!    raw frames and JPEG-compressed frames.
//!
//! Ground truth is read only to score.

pub mod camera;
mod score;
mod studies;

use super::{Options, Outcome};
use sim::Level;

/// The experiment's name.
pub const NAME: &str = "paper004";
/// Frames per second of every study (the paper's camera runs at 15–30 fps).
pub const FPS: f64 = 15.0;
/// Simulated seconds of the occlusion and illumination studies (the crowd's run is as long as
/// its people take to cross, plus a few seconds empty).
pub const DURATION_S: f64 = 30.0;

/// Run it.
///
/// # Errors
/// A scenario the camera cannot be built from, or a frame the pipeline refuses.
pub fn run(opts: &Options) -> crate::error::Result<Outcome> {
    let duration_s = opts.duration_s.unwrap_or(DURATION_S);
    let mut out = Outcome::new(NAME, Level::Pixel, opts, duration_s);
    studies::occlusion(opts, duration_s, &mut out)?;
    studies::illumination(opts, duration_s, &mut out)?;
    let crowd = studies::crowd(opts, duration_s, &mut out)?;
    let stream = studies::stream(opts, duration_s, &mut out)?;
    studies::bandwidth(&crowd, &stream, &mut out);
    out.paper = studies::paper();
    out.notes.insert(
        0,
        format!(
            "One camera (node 10 of the default room, 352x288 with its lens distortion) at {FPS} fps, the camera core's segmentation and particle filters with the scenario's default parameters; a reported person matches a true one within 1 m on the floor (the CLEAR MOT threshold), the nearest first."
        ),
    );
    Ok(out)
}
