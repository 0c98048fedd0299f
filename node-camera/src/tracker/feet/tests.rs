use super::*;
use crate::region::Grid;
use proto::msg::PixelBox;
use proto::sensor::rgb_to_hsi;

fn bbox(xmin: f32, ymin: f32, xmax: f32, ymax: f32) -> PixelBox {
    PixelBox {
        xmin,
        ymin,
        xmax,
        ymax,
    }
}

/// A region over the inclusive pixel box `b` (as segmentation reports it); the camera tests
/// share it.
pub(crate) fn region(b: PixelBox) -> Detection {
    Detection {
        centre: [0.5 * (b.xmin + b.xmax), 0.5 * (b.ymin + b.ymax)],
        foot: [0.5 * (b.xmin + b.xmax), b.ymax],
        bbox: b,
        area: ((b.xmax - b.xmin + 1.0) * (b.ymax - b.ymin + 1.0)) as u32,
        colour: rgb_to_hsi(0.0, 0.0, 0.0),
    }
}

/// A 40×30 mask (full-resolution grid) with the inclusive pixel boxes set.
fn mask(boxes: &[PixelBox]) -> (Vec<u8>, Grid) {
    let grid = Grid::new(40, 30, 1);
    let mut m = vec![0u8; grid.len()];
    for b in boxes {
        for y in b.ymin as usize..=b.ymax as usize {
            for x in b.xmin as usize..=b.xmax as usize {
                m[y * grid.width + x] = 1;
            }
        }
    }
    (m, grid)
}

#[test]
fn a_region_of_ones_own_gives_the_lower_edge_under_ones_own_columns() {
    // The filter's box ends at row 15 (on the person's upper body); its region at row 24.
    let people = [PersonEstimate::at_box(0, bbox(5.0, 4.0, 12.0, 15.0), Some(0))];
    let regions = [region(bbox(5.0, 4.0, 12.0, 24.0))];
    assert_eq!(lower_edges(&people, &regions, None), vec![Some(24.5)]);
    // With the mask: a shadow merged into the region beside the person, lower than their feet,
    // does not move the edge under the person's columns.
    let person = bbox(5.0, 4.0, 12.0, 24.0);
    let shadow = bbox(13.0, 20.0, 20.0, 28.0);
    let (m, grid) = mask(&[person, shadow]);
    let fg = Foreground::new(&m, grid).unwrap();
    let regions = [region(bbox(5.0, 4.0, 20.0, 28.0))];
    assert_eq!(lower_edges(&people, &regions, Some(&fg)), vec![Some(24.5)]);
}

#[test]
fn on_a_coarser_grid_the_edge_is_the_regions_own() {
    // Every second pixel and row: grid row 10 stands for frame rows 20 and 21, and a region
    // whose last grid row is 10 ends at 21.5 (as `RegionStats` and `region_box` have it).
    let grid = Grid::new(40, 30, 2);
    let mut m = vec![0u8; grid.len()];
    for gy in 2..=10 {
        for gx in 3..=6 {
            m[gy * grid.width + gx] = 1;
        }
    }
    let fg = Foreground::new(&m, grid).unwrap();
    let regions = [region(bbox(6.0, 4.0, 13.0, 21.0))];
    let people = [PersonEstimate::at_box(0, bbox(5.5, 3.5, 13.5, 12.0), Some(0))];
    let want = crate::tracker::manager::region_box(&regions[0]).ymax;
    assert_eq!(want, 21.5);
    assert_eq!(lower_edges(&people, &regions, Some(&fg)), vec![Some(want)]);
    assert_eq!(lower_edges(&people, &regions, None), vec![Some(want)]);
}

#[test]
fn people_merged_in_one_region_each_get_their_own_columns_lowest_foreground() {
    // Two people merged in one region: the left one nearer the camera (feet at row 27), the
    // right one farther (feet at row 20); a stray foreground pixel under the right one's
    // first column does not move its edge (the median of its columns').
    let near = bbox(2.0, 6.0, 9.0, 27.0);
    let far = bbox(10.0, 3.0, 16.0, 20.0);
    // Three stray columns: the lowest row of any column, or the columns' mean, would move it.
    let stray = bbox(10.0, 25.0, 12.0, 25.0);
    let (m, grid) = mask(&[near, far, stray]);
    let fg = Foreground::new(&m, grid).unwrap();
    let regions = [region(bbox(2.0, 3.0, 16.0, 27.0))];
    let people = [
        PersonEstimate::at_box(0, bbox(1.5, 5.5, 9.5, 18.0), Some(0)),
        PersonEstimate::at_box(1, bbox(9.5, 2.5, 16.5, 12.0), Some(0)),
    ];
    assert_eq!(
        lower_edges(&people, &regions, Some(&fg)),
        vec![Some(27.5), Some(20.5)]
    );
    // Without a mask a shared region says nothing: the filters' own boxes stand.
    assert_eq!(lower_edges(&people, &regions, None), vec![None, None]);
}

#[test]
fn a_filter_without_a_region_keeps_its_own_box() {
    let (m, grid) = mask(&[bbox(2.0, 6.0, 9.0, 27.0)]);
    let fg = Foreground::new(&m, grid).unwrap();
    let people = [PersonEstimate::at_box(0, bbox(20.0, 5.0, 28.0, 20.0), None)];
    let regions = [region(bbox(2.0, 6.0, 9.0, 27.0))];
    assert_eq!(lower_edges(&people, &regions, Some(&fg)), vec![None]);
}

#[test]
fn feet_below_a_box_in_the_box_of_someone_in_front_are_theirs() {
    // A far person's legs at the top of the image, near person walking in front of them
    // below: one region, the legs' foreground running on into the near person's.
    let near = bbox(2.0, 10.0, 12.0, 28.0);
    let legs = bbox(4.0, 0.0, 9.0, 10.0);
    let (m, grid) = mask(&[near, legs]);
    let fg = Foreground::new(&m, grid).unwrap();
    let regions = [region(bbox(2.0, 0.0, 12.0, 28.0))];
    let people = [
        PersonEstimate::at_box(0, bbox(1.5, 9.5, 12.5, 28.5), Some(0)),
        PersonEstimate::at_box(1, bbox(3.5, -0.5, 9.5, 8.0), Some(0)),
    ];
    let edges = lower_edges(&people, &regions, Some(&fg));
    assert_eq!(
        edges,
        vec![Some(28.5), Some(28.5)],
        "the legs' lowest foreground is the near feet"
    );
    assert!(
        !anothers_feet(&people, 0, 28.5),
        "the near person's feet are their own"
    );
    assert!(anothers_feet(&people, 1, 28.5), "the legs' are the near person's");
    // Not in another region, nor with no region: nobody stands in front.
    let apart = [
        people[0].clone(),
        PersonEstimate::at_box(1, bbox(3.5, -0.5, 9.5, 8.0), Some(1)),
    ];
    assert!(!anothers_feet(&apart, 1, 28.5));
    let lost = [
        people[0].clone(),
        PersonEstimate::at_box(1, bbox(3.5, -0.5, 9.5, 8.0), None),
    ];
    assert!(!anothers_feet(&lost, 1, 28.5));
    // Beside, not in front: the other's box spans under half the filter's columns.
    let beside = [
        PersonEstimate::at_box(0, bbox(8.0, 9.5, 18.0, 28.5), Some(0)),
        people[1].clone(),
    ];
    assert!(!anothers_feet(&beside, 1, 28.5));
    // Far below the other's box (beyond a quarter of its height): not their feet.
    assert!(!anothers_feet(&people, 1, 28.5 + 0.3 * 19.0));
    assert!(anothers_feet(&people, 1, 28.5 + 0.2 * 19.0));
}

#[test]
fn a_box_on_the_upper_body_alone_in_its_region_keeps_its_measured_feet() {
    // The mean box ends on the person's chest (the colour likelihood does not pin its lower
    // edge); the feet found below it are theirs: nobody else's box is there.
    let person = bbox(5.0, 4.0, 12.0, 24.0);
    let (m, grid) = mask(&[person]);
    let fg = Foreground::new(&m, grid).unwrap();
    let regions = [region(person)];
    let people = [PersonEstimate::at_box(0, bbox(4.5, 3.5, 12.5, 14.0), Some(0))];
    assert_eq!(lower_edges(&people, &regions, Some(&fg)), vec![Some(24.5)]);
    assert!(!anothers_feet(&people, 0, 24.5));
    // An index past the people is nobody's.
    assert!(!anothers_feet(&people, 3, 24.5));
}
