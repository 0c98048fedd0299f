//! Mask post-processing shared by the pipelines: 4-neighbour erosion (paper 004), box region
//! growing with merging of nearby areas (paper 004 §3.2.1) and 8-neighbour region growing
//! (paper 000 §6.1.1). Masks are one byte per processing-grid pixel, 0 = background.

use crate::detect::RegionStats;
use proto::sensor::Detection;
use proto::sensor::Frame;

/// A processing grid: every `step`-th pixel of every `step`-th row of the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    pub width: usize,
    pub height: usize,
    pub step: usize,
    pub frame_width: usize,
}

impl Grid {
    pub fn new(frame_width: u32, frame_height: u32, step: u32) -> Grid {
        let step = step.max(1) as usize;
        Grid {
            width: frame_width as usize / step,
            height: frame_height as usize / step,
            step,
            frame_width: frame_width as usize,
        }
    }

    pub fn len(&self) -> usize {
        self.width * self.height
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Byte offset in the frame buffer of grid pixel `(gx, gy)`.
    #[inline]
    pub fn frame_offset(&self, gx: usize, gy: usize) -> usize {
        (gy * self.step * self.frame_width + gx * self.step) * 3
    }

    #[inline]
    pub fn rgb(&self, frame: &Frame, gx: usize, gy: usize) -> [u8; 3] {
        let o = self.frame_offset(gx, gy);
        [frame.data[o], frame.data[o + 1], frame.data[o + 2]]
    }
}

/// Index of the first non-zero byte at or after `from`, eight bytes at a time (masks are
/// mostly zero).
pub fn first_set(mask: &[u8], from: usize) -> Option<usize> {
    let rest = mask.get(from..)?;
    let mut chunks = rest.chunks_exact(8);
    let mut base = from;
    for c in chunks.by_ref() {
        let word = u64::from_ne_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        if word != 0 {
            return c.iter().position(|&v| v != 0).map(|p| base + p);
        }
        base += 8;
    }
    chunks.remainder().iter().position(|&v| v != 0).map(|p| base + p)
}

/// 4-neighbour erosion: a pixel survives if it is set and at least `min_neighbours` of its
/// four neighbours are set (4 = classic erosion with a cross; 1 = only isolated pixels die).
/// The outermost rows and columns are cleared.
pub fn erode4(grid: &Grid, mask: &[u8], out: &mut [u8], min_neighbours: u8) {
    let (w, h) = (grid.width, grid.height);
    out.fill(0);
    if w < 3 || h < 3 {
        return;
    }
    for y in 1..h - 1 {
        let up = &mask[(y - 1) * w..y * w];
        let row = &mask[y * w..(y + 1) * w];
        let down = &mask[(y + 1) * w..(y + 2) * w];
        let o = &mut out[y * w..(y + 1) * w];
        for x in 1..w - 1 {
            let n = up[x] + down[x] + row[x - 1] + row[x + 1];
            o[x] = row[x] & u8::from(n >= min_neighbours);
        }
    }
}

/// Paper 004's region growing: find the first set pixel, grow a box around it while set
/// pixels lie on its border or across a gap of at most `merge` pixels beyond it (so nearby areas merge instead of
/// breaking up), then take the box's pixels as one region and clear them. Consumes `mask`.
/// Regions with fewer than `min_pixels` set pixels are dropped; at most `max_regions` kept.
#[allow(clippy::too_many_arguments)]
pub fn grow_boxes(
    grid: &Grid,
    mask: &mut [u8],
    frame: &Frame,
    merge: usize,
    min_pixels: u32,
    max_regions: usize,
    out: &mut Vec<Detection>,
) {
    let (w, h) = (grid.width, grid.height);
    let reach = merge + 1;
    let mut start = 0;
    while let Some(seed) = first_set(mask, start) {
        let (sx, sy) = (seed % w, seed / w);
        let (mut x0, mut y0, mut x1, mut y1) = (sx, sy, sx, sy);
        loop {
            let ex0 = x0.saturating_sub(reach);
            let ey0 = y0.saturating_sub(reach);
            let ex1 = (x1 + reach).min(w - 1);
            let ey1 = (y1 + reach).min(h - 1);
            let (mut nx0, mut ny0, mut nx1, mut ny1) = (x0, y0, x1, y1);
            for y in ey0..=ey1 {
                let row = &mask[y * w..(y + 1) * w];
                let mut scan = |a: usize, b: usize| {
                    if let Some(p) = row[a..=b].iter().position(|&v| v != 0) {
                        let q = b - row[a..=b].iter().rev().position(|&v| v != 0).unwrap_or(0);
                        nx0 = nx0.min(a + p);
                        nx1 = nx1.max(q);
                        ny0 = ny0.min(y);
                        ny1 = ny1.max(y);
                    }
                };
                if y < y0 || y > y1 {
                    scan(ex0, ex1);
                } else {
                    if ex0 < x0 {
                        scan(ex0, x0 - 1);
                    }
                    if x1 < ex1 {
                        scan(x1 + 1, ex1);
                    }
                }
            }
            if (nx0, ny0, nx1, ny1) == (x0, y0, x1, y1) {
                break;
            }
            (x0, y0, x1, y1) = (nx0, ny0, nx1, ny1);
        }
        let mut stats = RegionStats::start(x0 as u32, y0 as u32);
        stats.xmin = x1 as u32;
        stats.ymin = y1 as u32;
        stats.xmax = x0 as u32;
        stats.ymax = y0 as u32;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let i = y * w + x;
                if mask[i] != 0 {
                    mask[i] = 0;
                    stats.add(x as u32, y as u32, grid.rgb(frame, x, y));
                }
            }
        }
        if stats.n >= min_pixels && out.len() < max_regions {
            out.extend(stats.to_detection(grid.step as u32));
        }
        start = seed + 1;
    }
}

/// Paper 000's 8-neighbour region growing over a label map (0 = none, otherwise a class):
/// each connected set of equal labels is one region. Consumes `labels`; `stack` is scratch.
#[allow(clippy::too_many_arguments)]
pub fn grow_8(
    grid: &Grid,
    labels: &mut [u8],
    frame: &Frame,
    stack: &mut Vec<u32>,
    min_pixels: u32,
    max_regions: usize,
    out: &mut Vec<Detection>,
) {
    let (w, h) = (grid.width, grid.height);
    let mut start = 0;
    while let Some(seed) = first_set(labels, start) {
        let class = labels[seed];
        labels[seed] = 0;
        stack.clear();
        stack.push(seed as u32);
        let mut stats = RegionStats::start((seed % w) as u32, (seed / w) as u32);
        while let Some(i) = stack.pop() {
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            stats.add(x as u32, y as u32, grid.rgb(frame, x, y));
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let j = ny * w + nx;
                    if labels[j] == class {
                        labels[j] = 0;
                        stack.push(j as u32);
                    }
                }
            }
        }
        if stats.n >= min_pixels && out.len() < max_regions {
            out.extend(stats.to_detection(grid.step as u32));
        }
        start = seed + 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::ClusterTime;

    fn grid(w: usize, h: usize) -> Grid {
        Grid::new(w as u32, h as u32, 1)
    }

    fn set(mask: &mut [u8], w: usize, x0: usize, y0: usize, x1: usize, y1: usize) {
        for y in y0..=y1 {
            for x in x0..=x1 {
                mask[y * w + x] = 1;
            }
        }
    }

    #[test]
    fn first_set_finds_every_position() {
        for len in [0usize, 1, 7, 8, 9, 31] {
            for at in 0..len {
                let mut m = vec![0u8; len];
                m[at] = 3;
                for from in 0..=len {
                    let want = (at >= from).then_some(at);
                    assert_eq!(first_set(&m, from), want, "len {len} at {at} from {from}");
                }
            }
        }
        assert_eq!(first_set(&[0u8; 4], 9), None);
    }

    #[test]
    fn erosion_removes_isolated_pixels_keeps_blobs() {
        let g = grid(20, 20);
        let mut m = vec![0u8; g.len()];
        m[5 * 20 + 5] = 1;
        set(&mut m, 20, 10, 10, 14, 14);
        let mut out = vec![0u8; g.len()];
        erode4(&g, &m, &mut out, 2);
        assert_eq!(out[5 * 20 + 5], 0);
        assert_eq!(out[12 * 20 + 12], 1);
        assert_eq!(out[10 * 20 + 10], 1, "a corner has two set neighbours");
        erode4(&g, &m, &mut out, 4);
        assert_eq!(out[10 * 20 + 10], 0, "classic erosion eats corners");
    }

    #[test]
    fn boxes_merge_near_areas_and_split_far_ones() {
        let g = grid(60, 30);
        let f = Frame::new(60, 30, ClusterTime::ZERO);
        let mut m = vec![0u8; g.len()];
        set(&mut m, 60, 2, 2, 6, 10);
        set(&mut m, 60, 9, 3, 12, 12); // 2 px gap: merges with merge = 2
        set(&mut m, 60, 40, 5, 45, 20); // far away
        let mut out = Vec::new();
        grow_boxes(&g, &mut m.clone(), &f, 2, 4, 16, &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        assert_eq!((out[0].bbox.xmin, out[0].bbox.xmax), (2.0, 12.0));
        assert_eq!((out[0].bbox.ymin, out[0].bbox.ymax), (2.0, 12.0));
        assert_eq!(out[0].area, 45 + 40);
        out.clear();
        grow_boxes(&g, &mut m, &f, 1, 4, 16, &mut out);
        assert_eq!(out.len(), 3, "merge = 1 does not bridge a 2 px gap");
        assert!(m.iter().all(|&v| v == 0), "growing consumes the mask");
    }

    #[test]
    fn eight_neighbour_growing_joins_diagonals_only_same_class() {
        let g = grid(10, 10);
        let f = Frame::new(10, 10, ClusterTime::ZERO);
        let mut l = vec![0u8; g.len()];
        l[11] = 1;
        l[22] = 1; // diagonal neighbour
        l[33] = 2; // diagonal, other class
        let mut out = Vec::new();
        grow_8(&g, &mut l, &f, &mut Vec::new(), 1, 16, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].area, 2);
        assert_eq!(out[1].area, 1);
    }
}
