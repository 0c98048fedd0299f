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

/// A region over the inclusive pixel box `b` (as segmentation reports it).
fn region(b: PixelBox) -> Detection {
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
