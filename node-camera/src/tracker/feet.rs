//! Where each tracked person's feet are in this frame.
//!
//! Paper 004's 2D→3D unit ([`crate::tracker::ground`]) puts a person on the floor through the
//! lower corners of their box, and one camera's depth comes from that row alone. The filter's
//! colour likelihood does not pin the row: a box on the upper half of a uniformly coloured
//! person matches as well as one over all of them, so the mean box's lower edge wanders over
//! the body, and a few rows too high put the person a metre or more behind where they stand.
//! The foreground measured in the same frame does pin it:
//! - a region that supports this filter alone: the region's lower edge;
//! - a region several filters share (people merged in this view): per column of the filter's
//!   box inside the region, the lowest foreground pixel between the filter's top and the
//!   region's bottom, and the median of those (a neighbour's legs under a few columns do not
//!   move it);
//! - no region (the person is hidden or gone), or no foreground mask: the filter's own box, as
//!   the paper has it.
//!
//! Measured in `ocelli experiment paper004` (docs/paper004.md, "Where the feet are").

use crate::tracker::manager::{Foreground, PersonEstimate, region_box};
use proto::sensor::Detection;

/// The measured lower edge (frame pixels, continuous) of each of `people`, in order; `None`
/// where the filter's own box stands. `regions` are the frame's regions the tracker was given
/// (each estimate's `region` indexes them).
pub fn lower_edges(
    people: &[PersonEstimate],
    regions: &[Detection],
    foreground: Option<&Foreground<'_>>,
) -> Vec<Option<f32>> {
    people
        .iter()
        .map(|person| {
            let r = person.region?;
            let region = region_box(regions.get(r)?);
            let sharing = people.iter().filter(|q| q.region == Some(r)).count();
            if sharing == 1 {
                return Some(region.ymax);
            }
            let b = person.mean.bbox();
            let columns = (b.xmin.max(region.xmin), b.xmax.min(region.xmax));
            foreground?.lowest_edge(columns, (b.ymin.max(region.ymin), region.ymax))
        })
        .map(|edge| edge.filter(|e| e.is_finite()))
        .collect()
}

#[cfg(test)]
mod tests;
