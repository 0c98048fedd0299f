//! One camera at pixel level, as paper 004's experiments need it: the scenario's world rendered
//! (`world::render`) with people who walk in and out of view, an optional slow global
//! illumination change laid over the rendered frames, the background model (`node_camera`'s
//! segmenter), and then either segmentation alone (regions linked frame to frame by overlap)
//! or the camera's particle filters (`node_camera::ground_people`, the camera core's paper 004
//! mode). Per frame it records the truth (for scoring only), each method's people (image box
//! and ground position with the method's id) and, for the particle filters, the bytes each
//! mode would put on the wire: the camera core's people frames (`ground_people::PeopleSender`,
//! one per head step) and, for comparison, the same frames had every frame been sent.

use super::super::{ParticleTrace, PdfSlice, SampleSnapshot};
use nalgebra::Vector3;
use node_camera::ground_people::{GroundPeople, PeopleSender};
use node_camera::segment::{SegmentParams, Segmenter};
use node_camera::tracker::ground::ground_point;
use node_camera::tracker::manager::Foreground;
use node_camera::tracker::params::ParticleParams;
use proto::camera::CameraModel;
use proto::msg::{Envelope, Message, Mode, PixelBox};
use proto::scenario::Scenario;
use proto::sensor::{Detection, Frame};
use proto::{ClusterTime, NodeId};
use world::render::Renderer;
use world::{Target, Trajectory};

/// A person of a study: the target's size and colour, where they walk (`trajectory` from the
/// moment they enter) and when they are in the room.
#[derive(Clone, Debug)]
pub struct Walker {
    pub target: Target,
    pub enter_s: f64,
    pub leave_s: f64,
}

impl Walker {
    /// The target frozen where it is at `t`, if it is in the room then.
    fn at(&self, t: f64) -> Option<Target> {
        if t < self.enter_s || t >= self.leave_s {
            return None;
        }
        let (p, _) = self.target.trajectory.at(t - self.enter_s);
        // A zero-length path: the renderer puts the target at its only point whatever `t`.
        Some(Target {
            trajectory: Trajectory::Path {
                waypoints: vec![p, p],
                speed: 1.0,
                pauses: Vec::new(),
            },
            ..self.target.clone()
        })
    }
}

/// A slow global illumination change laid over the rendered frames: the gain of each colour
/// channel goes linearly from 1 at `from_s` to `end_gain` at `to_s` (the renderer's own
/// change, ±8% over 40 s, stays underneath).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Illumination {
    pub end_gain: [f64; 3],
    pub from_s: f64,
    pub to_s: f64,
}

impl Illumination {
    pub fn gain(&self, t: f64) -> [f64; 3] {
        let f = ((t - self.from_s) / (self.to_s - self.from_s).max(1e-9)).clamp(0.0, 1.0);
        self.end_gain.map(|g| 1.0 + f * (g - 1.0))
    }

    fn apply(&self, t: f64, frame: &mut Frame) {
        let g = self.gain(t);
        for px in frame.data.chunks_exact_mut(3) {
            for (v, g) in px.iter_mut().zip(g) {
                *v = (f64::from(*v) * g).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// What the camera does with its regions.
#[derive(Clone, Debug, PartialEq)]
pub enum Tracker {
    /// Segmentation alone: each region is a person; a region overlapping one of the previous
    /// frame's keeps its id, any other gets a new one.
    Segmentation,
    /// The particle filters with these parameters.
    Particle(ParticleParams),
}

/// One study's camera run.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The world (walls) and the camera node.
    pub scenario: Scenario,
    pub camera: u32,
    pub walkers: Vec<Walker>,
    pub fps: f64,
    pub duration_s: f64,
    pub illumination: Option<Illumination>,
}

/// A true person in a frame (scoring only).
#[derive(Clone, Debug)]
pub struct TruePerson {
    pub id: u32,
    pub ground: [f64; 2],
    /// The solid's projected box.
    pub bbox: PixelBox,
    /// Its centre projects inside the image.
    pub in_view: bool,
    /// The view ray to its centre crosses a wall (partly hidden).
    pub occluded: bool,
}

/// A person the camera reports in a frame.
#[derive(Clone, Debug)]
pub struct Reported {
    pub id: u32,
    pub bbox: PixelBox,
    /// Ground position, m; `None` above the horizon.
    pub ground: Option<[f64; 2]>,
}

/// One frame's record.
#[derive(Clone, Debug)]
pub struct FrameRecord {
    pub t: f64,
    pub truth: Vec<TruePerson>,
    pub reported: Vec<Reported>,
    /// Bytes of the people frame the camera sends this frame, if it is the step's (particle
    /// filters only), the people in it and the histograms among them.
    pub observation_bytes: usize,
    pub people_sent: usize,
    pub histograms_sent: usize,
    /// Bytes of this frame's people frame, were every frame sent.
    pub every_frame_bytes: usize,
    /// `observation_bytes` with a deployment's time stamps (nanoseconds since the Unix epoch,
    /// [`WALL_CLOCK_EPOCH`] + the run's time) instead of the run's (from 0).
    pub wall_clock_bytes: usize,
    /// Bytes of every filter's sample set, were they asked for this frame, and how many sets.
    pub sample_set_bytes: usize,
    pub sample_sets: usize,
    /// Bytes of the frame as a JPEG, when asked for.
    pub jpeg_bytes: Option<usize>,
}

impl FrameRecord {
    /// A frame at `t` with its `truth`, nothing reported or sent yet.
    pub fn new(t: f64, truth: Vec<TruePerson>) -> FrameRecord {
        FrameRecord {
            t,
            truth,
            reported: Vec::new(),
            observation_bytes: 0,
            people_sent: 0,
            histograms_sent: 0,
            every_frame_bytes: 0,
            wall_clock_bytes: 0,
            sample_set_bytes: 0,
            sample_sets: 0,
            jpeg_bytes: None,
        }
    }
}

/// A camera run.
#[derive(Clone, Debug)]
pub struct CameraRun {
    pub frames: Vec<FrameRecord>,
    pub width: u32,
    pub height: u32,
    /// Filters alive after the last frame (particle filters only).
    pub live_at_end: usize,
    /// The filters' pdf per frame and one frame's samples (particle filters only).
    pub particles: Option<ParticleTrace>,
}

/// Bin width of the pdf's marginals, px.
const PDF_BIN_PX: u32 = 4;
/// The sample snapshot is taken this many frames into the first stretch in which a person in
/// view is hidden behind a wall (else at the run's middle).
const SNAPSHOT_FRAMES_IN: usize = 4;

/// Gathers a particle run's [`ParticleTrace`] frame by frame.
struct ParticleRecorder {
    trace: ParticleTrace,
    hidden_run: usize,
    middle: Option<SampleSnapshot>,
}

impl ParticleRecorder {
    fn new(width: u32, height: u32) -> Self {
        ParticleRecorder {
            trace: ParticleTrace {
                width,
                height,
                bin_px: PDF_BIN_PX,
                ..ParticleTrace::default()
            },
            hidden_run: 0,
            middle: None,
        }
    }

    fn record(&mut self, t: f64, frame: &Frame, people: &GroundPeople, truth: &[TruePerson], middle: bool) {
        let tracker = people.tracker();
        let bins = |len: u32| len.div_ceil(PDF_BIN_PX) as usize;
        let mut slice = PdfSlice {
            t,
            columns: vec![0.0; bins(self.trace.width)],
            rows: vec![0.0; bins(self.trace.height)],
        };
        let mut samples = Vec::new();
        let mut means = Vec::new();
        for id in tracker.ids() {
            let Some(f) = tracker.filter(id) else { continue };
            for s in f.samples() {
                let (x, y) = (s.state.x, s.state.y);
                if x >= 0.0 && y >= 0.0 && x < self.trace.width as f32 && y < self.trace.height as f32 {
                    slice.columns[x as usize / PDF_BIN_PX as usize] += s.weight;
                    slice.rows[y as usize / PDF_BIN_PX as usize] += s.weight;
                }
                samples.push([x, y, s.weight]);
            }
            let m = f.mean();
            means.push([m.x, m.y]);
        }
        self.trace.frames.push(slice);
        let hidden = truth.iter().any(|p| p.in_view && p.occluded);
        self.hidden_run = if hidden { self.hidden_run + 1 } else { 0 };
        let snapshot = |why: &str| {
            image::RgbImage::from_raw(frame.width, frame.height, frame.data.clone()).map(|image| {
                SampleSnapshot {
                    t,
                    image,
                    samples: samples.clone(),
                    means: means.clone(),
                    why: why.into(),
                }
            })
        };
        if self.trace.snapshot.is_none() && self.hidden_run == SNAPSHOT_FRAMES_IN && !means.is_empty() {
            self.trace.snapshot = snapshot("person partly hidden");
        }
        if middle && !means.is_empty() {
            self.middle = snapshot("mid-run");
        }
    }

    fn finish(mut self) -> ParticleTrace {
        if self.trace.snapshot.is_none() {
            self.trace.snapshot = self.middle;
        }
        self.trace
    }
}

/// The quality of the JPEGs of the bandwidth study.
pub const JPEG_QUALITY: u8 = 75;

/// Run `tracker` on `setup`'s camera with seed `seed`; every `jpeg_every`-th frame is also
/// compressed (0: none).
///
/// # Errors
/// A camera the scenario cannot model, parameters out of range, or a frame the pipeline
/// refuses.
pub fn run(
    setup: &Setup,
    tracker: &Tracker,
    seed: u64,
    jpeg_every: usize,
) -> crate::error::Result<CameraRun> {
    let s = &setup.scenario;
    let camera = s.camera_model(setup.camera)?;
    let renderer = Renderer::for_node(s, setup.camera, seed)?;
    let (width, height) = renderer.size();
    let mut params = SegmentParams::for_scenario(s, width);
    params.adaptive_background = params.adaptive_background.scaled_to_fps(setup.fps);
    let mut segmenter = Segmenter::new(&params);
    let mut people = match tracker {
        Tracker::Particle(p) => Some(GroundPeople::new(p, setup.fps, seed)?),
        Tracker::Segmentation => None,
    };
    let mut recorder = people.as_ref().map(|_| ParticleRecorder::new(width, height));
    // What the camera core sends (one people frame per head step), and every frame's.
    let hs_weight = match tracker {
        Tracker::Particle(p) => f64::from(p.hs_weight),
        Tracker::Segmentation => 0.0,
    };
    let mut senders = [
        PeopleSender::new(s.method.step_ms, hs_weight),
        PeopleSender::new(0, hs_weight),
    ];
    let mut linker = RegionLinker::default();
    let mut frame = Frame::new(0, 0, ClusterTime::ZERO);
    let mut regions: Vec<Detection> = Vec::new();
    let n = (setup.duration_s * setup.fps).floor() as usize;
    let mut frames = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 / setup.fps;
        let present: Vec<Target> = setup.walkers.iter().filter_map(|w| w.at(t)).collect();
        let captured = ClusterTime::from_secs_f64(t);
        renderer.render(&present, t, captured, &mut frame);
        if let Some(light) = &setup.illumination {
            light.apply(t, &mut frame);
        }
        segmenter.process(&frame, &mut regions)?;
        let mut rec = FrameRecord::new(t, present.iter().map(|p| truth_of(s, &camera, p, t)).collect());
        rec.jpeg_bytes = (jpeg_every > 0 && k % jpeg_every == 0)
            .then(|| jpeg_size(&frame))
            .transpose()?;
        match people.as_mut() {
            Some(people) => {
                let foreground = match &segmenter {
                    Segmenter::AdaptiveBackground(seg) => Foreground::of(seg),
                    Segmenter::ColourDifference(_) => None,
                };
                people.track(&camera, &frame, &regions, foreground)?;
                // As the camera node does (`hold-still-s`; the studies keep the paper's 0).
                if let Segmenter::AdaptiveBackground(seg) = &mut segmenter {
                    seg.hold(people.held());
                }
                record_people(people, &mut senders, setup.camera, &mut rec)?;
                if let Some(r) = recorder.as_mut() {
                    r.record(t, &frame, people, &rec.truth, k == n / 2);
                }
            }
            None => {
                for (id, d) in linker.link(&regions) {
                    rec.reported.push(Reported {
                        id,
                        bbox: d.bbox,
                        ground: foot_position(&camera, &d.bbox),
                    });
                }
            }
        }
        frames.push(rec);
    }
    Ok(CameraRun {
        frames,
        width,
        height,
        live_at_end: people.map_or(0, |p| p.tracker().ids().len()),
        particles: recorder.map(ParticleRecorder::finish),
    })
}

/// A deployment's time 0 for [`FrameRecord::wall_clock_bytes`]: 2026-01-01T00:00:00Z, ns
/// since the Unix epoch (cluster time is wall-clock time).
pub const WALL_CLOCK_EPOCH: ClusterTime = ClusterTime(1_767_225_600_000_000_000);

/// The particle filters' people of this frame into `rec`, with the bytes of each mode:
/// `senders` are the camera core's (one people frame per step) and one that sends every frame.
/// No head and no priors here: every person goes out ungated, as a camera's people do until a
/// head tracks them (and all of them do in centralized fusion).
fn record_people(
    people: &GroundPeople,
    senders: &mut [PeopleSender; 2],
    node: u32,
    rec: &mut FrameRecord,
) -> crate::error::Result<()> {
    let time = ClusterTime::from_secs_f64(rec.t);
    let envelope = |body: Message| Envelope {
        source: NodeId(node),
        seq: 0,
        time,
        body,
    };
    let ids = people.tracker().ids();
    for (k, sender) in senders.iter_mut().enumerate() {
        sender.retain(&ids);
        if people.latest().is_empty() || !sender.due(time) {
            continue;
        }
        let frame = sender.frame(
            time,
            Mode::Active,
            people.latest().iter().map(|g| (g, None)),
            Vec::new(),
        );
        let bytes = proto::wire::encode(&envelope(Message::PeopleFrame(frame.clone())))?.len();
        if k == 0 {
            let wall = |t: ClusterTime| ClusterTime(t.0 + WALL_CLOCK_EPOCH.0);
            let deployed = Envelope {
                time: wall(time),
                body: Message::PeopleFrame(proto::msg::PeopleFrame {
                    captured: wall(frame.captured),
                    ..frame.clone()
                }),
                ..envelope(Message::Heartbeat)
            };
            rec.wall_clock_bytes = proto::wire::encode(&deployed)?.len();
            rec.observation_bytes = bytes;
            rec.people_sent = frame.people.len();
            rec.histograms_sent = frame.people.iter().filter(|p| p.histogram.is_some()).count();
        } else {
            rec.every_frame_bytes = bytes;
        }
    }
    for g in people.latest() {
        let bbox = people
            .tracker()
            .filter(g.local)
            .map(|f| f.mean().bbox())
            .unwrap_or(PixelBox {
                xmin: 0.0,
                ymin: 0.0,
                xmax: 0.0,
                ymax: 0.0,
            });
        rec.reported.push(Reported {
            id: g.local,
            bbox,
            ground: Some(g.position),
        });
    }
    for set in people.samples(None) {
        rec.sample_set_bytes += proto::wire::encode(&envelope(Message::SampleSet(set)))?.len();
        rec.sample_sets += 1;
    }
    Ok(())
}

/// Where the rays of a box's lower corners meet the floor, midway (paper 004 §3.2.3's
/// position, as the particle mode computes it).
pub fn foot_position(camera: &CameraModel, b: &PixelBox) -> Option<[f64; 2]> {
    let left = ground_point(camera, [f64::from(b.xmin), f64::from(b.ymax)])?;
    let right = ground_point(camera, [f64::from(b.xmax), f64::from(b.ymax)])?;
    let mid = 0.5 * (left + right);
    Some([mid.x, mid.y])
}

fn truth_of(s: &Scenario, camera: &CameraModel, p: &Target, t: f64) -> TruePerson {
    let c = p.position_at(t);
    let k = &camera.intrinsics;
    let in_view = camera.project(&c).is_some_and(|px| {
        px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(k.width) && px.y < f64::from(k.height)
    });
    let mut bbox = PixelBox {
        xmin: f32::MAX,
        ymin: f32::MAX,
        xmax: f32::MIN,
        ymax: f32::MIN,
    };
    let half = Vector3::new(p.size[0], p.size[1], p.size[2]) * 0.5;
    for corner in 0..8 {
        let sign = |bit: usize| if corner & bit == 0 { -1.0 } else { 1.0 };
        let q = c + Vector3::new(sign(1) * half.x, sign(2) * half.y, sign(4) * half.z);
        if let Some(px) = camera.project(&q) {
            bbox.xmin = bbox.xmin.min(px.x as f32);
            bbox.ymin = bbox.ymin.min(px.y as f32);
            bbox.xmax = bbox.xmax.max(px.x as f32);
            bbox.ymax = bbox.ymax.max(px.y as f32);
        }
    }
    TruePerson {
        id: p.id,
        ground: [c.x, c.y],
        bbox,
        in_view,
        occluded: s.world.occluded(&camera.pose.centre(), &c),
    }
}

/// Bytes of `frame` as a baseline JPEG at [`JPEG_QUALITY`].
fn jpeg_size(frame: &Frame) -> crate::error::Result<usize> {
    let mut out = Vec::new();
    let mut enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY);
    enc.encode(
        &frame.data,
        frame.width,
        frame.height,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out.len())
}

/// Intersection over union of two pixel boxes.
pub fn iou(a: &PixelBox, b: &PixelBox) -> f32 {
    let w = (a.xmax.min(b.xmax) - a.xmin.max(b.xmin)).max(0.0);
    let h = (a.ymax.min(b.ymax) - a.ymin.max(b.ymin)).max(0.0);
    let inter = w * h;
    let area = |b: &PixelBox| (b.xmax - b.xmin).max(0.0) * (b.ymax - b.ymin).max(0.0);
    let union = area(a) + area(b) - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// Segmentation alone's identities: a region that overlaps a region of the previous frame
/// takes its id (the best overlap first, each id once), any other region a new id.
#[derive(Debug, Default)]
struct RegionLinker {
    previous: Vec<(u32, PixelBox)>,
    next_id: u32,
}

impl RegionLinker {
    fn link<'a>(&mut self, regions: &'a [Detection]) -> Vec<(u32, &'a Detection)> {
        let mut pairs: Vec<(f32, usize, usize)> = Vec::new();
        for (i, d) in regions.iter().enumerate() {
            for (j, (_, b)) in self.previous.iter().enumerate() {
                let o = iou(&d.bbox, b);
                if o > 0.0 {
                    pairs.push((o, i, j));
                }
            }
        }
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut ids: Vec<Option<u32>> = vec![None; regions.len()];
        let mut taken = vec![false; self.previous.len()];
        for (_, i, j) in pairs {
            if ids[i].is_none() && !taken[j] {
                ids[i] = Some(self.previous[j].0);
                taken[j] = true;
            }
        }
        let out: Vec<(u32, &Detection)> = regions
            .iter()
            .zip(ids)
            .map(|(d, id)| {
                let id = id.unwrap_or_else(|| {
                    self.next_id += 1;
                    self.next_id
                });
                (id, d)
            })
            .collect();
        self.previous = out.iter().map(|(id, d)| (*id, d.bbox)).collect();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region(x: f32) -> Detection {
        Detection {
            centre: [x + 5.0, 5.0],
            foot: [x + 5.0, 10.0],
            bbox: PixelBox {
                xmin: x,
                ymin: 0.0,
                xmax: x + 10.0,
                ymax: 10.0,
            },
            area: 100,
            colour: proto::msg::ColourSignature {
                hue: 0.0,
                saturation: 0.0,
                intensity: 0.0,
            },
        }
    }

    #[test]
    fn the_linker_keeps_ids_of_overlapping_regions_and_gives_new_ones_otherwise() {
        let mut l = RegionLinker::default();
        let a: Vec<u32> = l.link(&[region(0.0), region(50.0)]).iter().map(|p| p.0).collect();
        assert_eq!(a, vec![1, 2]);
        // The first moves a little, the second splits in two: one half keeps its id.
        let b: Vec<u32> = l
            .link(&[region(2.0), region(48.0), region(56.0)])
            .iter()
            .map(|p| p.0)
            .collect();
        assert_eq!(b[0], 1);
        assert!(b[1..].contains(&2) && b[1..].contains(&3), "{b:?}");
        // Lost for a frame: a new id when it comes back.
        assert!(l.link(&[]).is_empty());
        assert_eq!(l.link(&[region(2.0)])[0].0, 4);
    }

    #[test]
    fn the_illumination_ramps_from_one_to_its_end_gain() {
        let light = Illumination {
            end_gain: [0.5, 0.7, 1.0],
            from_s: 10.0,
            to_s: 20.0,
        };
        assert_eq!(light.gain(0.0), [1.0; 3]);
        assert_eq!(light.gain(15.0), [0.75, 0.85, 1.0]);
        assert_eq!(light.gain(30.0), [0.5, 0.7, 1.0]);
    }
}
