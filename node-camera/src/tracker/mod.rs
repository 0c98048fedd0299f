//! Paper 004's smart camera tracker (§2.2–2.5, §3.2): one colour-histogram particle filter
//! per person, started on foreground regions the background model finds and destroyed when
//! none supports it, and the 2D → 3D conversion of each person's box to a ground-plane
//! position with width, height and covariance.
//!
//! [`histogram`] is the colour model (eq. 4–8), [`motion`] the prediction step's models,
//! [`resample`] the choose-samples step, [`filter`] one person's filter (with self-adaptation,
//! eq. 9), [`manager`] the multi-person tracker (with [`fragment`], the parts of its people that
//! start no filter), [`feet`] where each person's box meets the
//! floor in the frame's foreground, [`ground`] the 2D → 3D conversion unit,
//! [`bayer`] the raw-sensor input, [`params`] the parameters, [`scene`] and [`bench`] the
//! synthetic frames and the timing function.

pub mod bayer;
pub mod bench;
pub mod boxes;
pub mod feet;
pub mod filter;
pub mod fragment;
pub mod ground;
pub mod histogram;
pub mod manager;
pub mod motion;
pub mod params;
pub mod resample;
pub mod scene;
