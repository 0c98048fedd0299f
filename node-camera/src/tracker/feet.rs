//! Where each tracked person's feet are in this frame.
//!
//! Paper 004's 2D→3D unit ([`crate::tracker::ground`]) puts a person on the floor through the
//! lower corners of their box, and one camera's depth comes from that row alone. The filter's
//! colour likelihood does not pin the row: a box on the upper half of a uniformly coloured
//! person matches as well as one over all of them, so the mean box's lower edge wanders over
//! the body, and a few rows too high put the person a metre or more behind where they stand.
//! The foreground measured in the same frame does pin it, in the region that supports the
//! filter: per column of the filter's box inside the region, the lowest foreground pixel
//! below the filter's top, and the median of those columns. The median keeps a neighbour's
//! legs under a few columns, or a shadow or a newcomer merged into the region beside the
//! person, from moving it. Without a mask, a region only this filter holds gives its own lower
//! edge (a region several share says nothing of who stands lowest). With no region (the person
//! is hidden or gone) the filter's own box stands, as the paper has it.
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
            let b = person.mean.bbox();
            let columns = (b.xmin.max(region.xmin), b.xmax.min(region.xmax));
            let rows = (b.ymin.max(region.ymin), region.ymax);
            match foreground {
                Some(fg) => fg.lowest_edge(columns, rows),
                None => {
                    let alone = people.iter().filter(|q| q.region == Some(r)).count() == 1;
                    alone.then_some(region.ymax)
                }
            }
        })
        .map(|edge| edge.filter(|e| e.is_finite()))
        .collect()
}

#[cfg(test)]
mod tests;
