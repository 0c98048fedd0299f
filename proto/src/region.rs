//! The floor a head covers: a scenario's `region = [xmin, ymin, xmax, ymax]`, metres. The
//! server hands tracks over by it and a head starts tracks by it, so both read it alike.

/// Distance from floor point `(x, y)` to region `r` (0 inside).
pub fn distance_to_region(r: &[f64; 4], x: f64, y: f64) -> f64 {
    let dx = (r[0] - x).max(0.0).max(x - r[2]);
    let dy = (r[1] - y).max(0.0).max(y - r[3]);
    dx.hypot(dy)
}

/// Whether floor point `(x, y)` lies in region `r` shrunk by `margin` on every side (grown,
/// for a negative margin).
pub fn inside_region(r: &[f64; 4], x: f64, y: f64, margin: f64) -> bool {
    x >= r[0] + margin && x <= r[2] - margin && y >= r[1] + margin && y <= r[3] - margin
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_and_inside() {
        let r = [0.0, 0.0, 6.0, 8.0];
        assert_eq!(distance_to_region(&r, 3.0, 3.0), 0.0);
        assert!((distance_to_region(&r, 9.0, 12.0) - 5.0).abs() < 1e-12);
        assert!(inside_region(&r, 5.5, 1.0, 0.25));
        assert!(!inside_region(&r, 5.9, 1.0, 0.25));
        assert!(inside_region(&r, 6.4, -0.4, -0.5), "grown by half a metre");
        assert!(!inside_region(&r, 6.6, 1.0, -0.5));
    }
}
