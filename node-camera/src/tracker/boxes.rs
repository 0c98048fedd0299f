//! Overlap of pixel boxes (continuous coordinates, `xmin ≤ xmax`): what the tracker uses to
//! relate samples, filters and foreground regions.

use proto::msg::PixelBox;

pub fn area(b: &PixelBox) -> f32 {
    (b.xmax - b.xmin).max(0.0) * (b.ymax - b.ymin).max(0.0)
}

pub fn intersection(a: &PixelBox, b: &PixelBox) -> f32 {
    let h = a.ymax.min(b.ymax) - a.ymin.max(b.ymin);
    shared_width(a, b) * h.max(0.0)
}

/// The width of the columns two boxes share, 0 when they share none.
pub fn shared_width(a: &PixelBox, b: &PixelBox) -> f32 {
    (a.xmax.min(b.xmax) - a.xmin.max(b.xmin)).max(0.0)
}

/// Intersection over union, 0 for boxes without area.
pub fn iou(a: &PixelBox, b: &PixelBox) -> f32 {
    let i = intersection(a, b);
    let u = area(a) + area(b) - i;
    if u > 0.0 { i / u } else { 0.0 }
}

/// Intersection over the smaller box's area, 0 when either has none: 1 for a box inside
/// another, whatever their sizes.
pub fn overlap_of_smaller(a: &PixelBox, b: &PixelBox) -> f32 {
    let smaller = area(a).min(area(b));
    if smaller > 0.0 {
        intersection(a, b) / smaller
    } else {
        0.0
    }
}

/// The columns two finite boxes share over the narrower box's width, 0 when either has none:
/// 1 for boxes stacked in one column span, whatever their heights.
pub fn column_overlap(a: &PixelBox, b: &PixelBox) -> f32 {
    let narrower = (a.xmax - a.xmin).min(b.xmax - b.xmin);
    if narrower > 0.0 {
        shared_width(a, b) / narrower
    } else {
        0.0
    }
}

/// The smallest box holding both.
pub fn union(a: &PixelBox, b: &PixelBox) -> PixelBox {
    PixelBox {
        xmin: a.xmin.min(b.xmin),
        ymin: a.ymin.min(b.ymin),
        xmax: a.xmax.max(b.xmax),
        ymax: a.ymax.max(b.ymax),
    }
}

pub fn contains(b: &PixelBox, p: [f32; 2]) -> bool {
    (b.xmin..=b.xmax).contains(&p[0]) && (b.ymin..=b.ymax).contains(&p[1])
}

pub fn is_finite(b: &PixelBox) -> bool {
    [b.xmin, b.ymin, b.xmax, b.ymax].iter().all(|v| v.is_finite())
}

/// A box from its sides (tests).
#[cfg(test)]
pub(crate) fn from_sides(xmin: f32, ymin: f32, xmax: f32, ymax: f32) -> PixelBox {
    PixelBox {
        xmin,
        ymin,
        xmax,
        ymax,
    }
}

#[cfg(test)]
mod tests {
    use super::from_sides as b;
    use super::*;

    #[test]
    fn overlap_by_hand() {
        let a = b(0.0, 0.0, 10.0, 10.0);
        assert_eq!(iou(&a, &a), 1.0);
        // Half overlap: 50 / 150.
        assert!((iou(&a, &b(5.0, 0.0, 15.0, 10.0)) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(iou(&a, &b(20.0, 0.0, 30.0, 10.0)), 0.0);
        assert_eq!(iou(&b(1.0, 1.0, 1.0, 1.0), &b(1.0, 1.0, 1.0, 1.0)), 0.0);
        assert!(contains(&a, [10.0, 0.0]) && !contains(&a, [10.1, 5.0]));
        assert!(!is_finite(&b(0.0, f32::NAN, 1.0, 1.0)));
        // Stacked: every column of the narrower box, no area in common.
        assert_eq!(column_overlap(&a, &b(2.0, 20.0, 8.0, 30.0)), 1.0);
        assert_eq!(column_overlap(&a, &b(5.0, 0.0, 25.0, 10.0)), 0.5);
        assert_eq!(column_overlap(&a, &b(10.0, 0.0, 20.0, 10.0)), 0.0);
        assert_eq!(column_overlap(&a, &b(3.0, 0.0, 3.0, 10.0)), 0.0);
    }
}
