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
//! The lowest foreground is not always the filter's own person's. When someone walks in front
//! of a person and hides them from the knees down, the foreground under the hidden person's
//! box runs on into the one in front, and the lowest foreground in its columns is the feet of
//! the person in front: a far person's legs at the top of the image above someone near the
//! camera, or someone in a group behind the one before them. On the floor the hidden person
//! would stand at the other's feet, a second report of that person (metres from where the
//! hidden one stands, when they are far). [`anothers_feet`] finds that case; nothing in the
//! frame measures where the hidden person stands then, so the camera does not report them in
//! that frame ([`crate::ground_people`]).
//!
//! Measured in `ocelli experiment paper004` (docs/paper004.md, "Where the feet are", "Feet that
//! are another's").

use crate::tracker::boxes;
use crate::tracker::manager::{Foreground, PersonEstimate, region_box};
use proto::sensor::Detection;

/// The feet found below a filter's box are another filter's when they lie in that filter's
/// box, or below it by no more than this share of its height (its own lower edge wanders as
/// a box's does) ...
pub const OTHER_BOX_SLACK: f32 = 0.25;
/// ... and that box spans at least this share of the filter's columns (a neighbour beside
/// them, whose box only touches theirs, does not stand in front).
pub const SHARED_COLUMNS: f32 = 0.5;

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

/// Whether the lower edge `edge` measured for `people[i]` ([`lower_edges`]) is the feet of
/// someone in front of them: it lies below the filter's box, in (or just below,
/// [`OTHER_BOX_SLACK`]) the box of another filter of the same region that reaches lower and
/// spans [`SHARED_COLUMNS`] of the filter's columns.
pub fn anothers_feet(people: &[PersonEstimate], i: usize, edge: f32) -> bool {
    let Some(me) = people.get(i) else {
        return false;
    };
    let b = me.mean.bbox();
    if me.region.is_none()
        || b.xmax.partial_cmp(&b.xmin) != Some(std::cmp::Ordering::Greater)
        || edge.partial_cmp(&b.ymax) != Some(std::cmp::Ordering::Greater)
    {
        return false;
    }
    people.iter().enumerate().any(|(j, other)| {
        let o = other.mean.bbox();
        j != i
            && boxes::is_finite(&o)
            && other.region == me.region
            && o.ymax > b.ymax
            && o.ymin < edge
            && edge <= o.ymax + OTHER_BOX_SLACK * (o.ymax - o.ymin)
            && boxes::shared_width(&b, &o) >= SHARED_COLUMNS * (b.xmax - b.xmin)
    })
}

#[cfg(test)]
pub(crate) mod tests;
