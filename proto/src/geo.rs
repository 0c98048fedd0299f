//! Where the site is on Earth: the optional `[world.geo]` of a scenario, and the conversion of
//! the world's local metres to WGS84 latitude, longitude and altitude for Google Earth (KML) and
//! Foxglove's `LocationFix`.
//!
//! The world frame is right-handed, z up, in metres. `origin = [lat, lon, alt]` is where the
//! world's `(0, 0, 0)` lies: degrees of WGS84 latitude and longitude, and the altitude of the
//! floor in metres above mean sea level. `heading-deg` is the compass bearing of the world's +y
//! axis, clockwise from true north: 0 puts +x east and +y north; 90 puts +y east and +x south.
//!
//! The conversion is a local tangent plane: north and east metres become degrees through the
//! WGS84 meridian and prime-vertical radii of curvature at the origin, and altitude is the
//! origin's plus z. At room and building scale this is exact to well below a centimetre
//! horizontally (the neglected terms grow as distance² / Earth radius: 1.6 mm at 100 m); the
//! Earth's curvature would lower a point 1 km away by 8 cm, which is also neglected. Sites
//! larger than a few kilometres need a proper geodetic transform.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// WGS84 semi-major axis, m.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 first eccentricity squared.
pub const WGS84_E2: f64 = 6.694_379_990_141_3e-3;

/// A scenario's `[world.geo]`: where the world's origin is and which way it faces.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Geo {
    /// `[latitude°, longitude°, altitude m above mean sea level]` of the world's `(0, 0, 0)`.
    pub origin: [f64; 3],
    /// Compass bearing of the world's +y axis, degrees clockwise from true north.
    #[serde(default)]
    pub heading_deg: f64,
}

/// A `[world.geo]` that cannot be used.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum GeoError {
    #[error("world.geo.origin: {0:?} is not finite")]
    NotFinite([f64; 3]),
    #[error(
        "world.geo.origin: latitude {0}° is outside [-89.9, 89.9] (a tangent plane at a pole has no east)"
    )]
    Latitude(f64),
    #[error("world.geo.origin: longitude {0}° is outside [-180, 180]")]
    Longitude(f64),
    #[error("world.geo.heading-deg: {0} is not finite")]
    Heading(f64),
}

/// A WGS84 position.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LatLonAlt {
    pub lat: f64,
    pub lon: f64,
    pub alt: f64,
}

impl Geo {
    /// Check the numbers.
    ///
    /// # Errors
    /// A non-finite number, a latitude at a pole or beyond, a longitude beyond ±180°.
    pub fn validate(&self) -> Result<(), GeoError> {
        let [lat, lon, _] = self.origin;
        if !self.origin.iter().all(|v| v.is_finite()) {
            return Err(GeoError::NotFinite(self.origin));
        }
        if !(-89.9..=89.9).contains(&lat) {
            return Err(GeoError::Latitude(lat));
        }
        if !(-180.0..=180.0).contains(&lon) {
            return Err(GeoError::Longitude(lon));
        }
        if !self.heading_deg.is_finite() {
            return Err(GeoError::Heading(self.heading_deg));
        }
        Ok(())
    }

    /// Metres per radian of latitude (meridian radius M) and of longitude (N cos φ) at the
    /// origin.
    fn radii(&self) -> (f64, f64) {
        let phi = self.origin[0].to_radians();
        let s2 = phi.sin().powi(2);
        let w = (1.0 - WGS84_E2 * s2).sqrt();
        let meridian = WGS84_A * (1.0 - WGS84_E2) / (w * w * w);
        let prime_vertical = WGS84_A / w;
        (meridian, prime_vertical * phi.cos())
    }

    /// World `[x, y]` → `(east, north)` metres from the origin.
    pub fn east_north(&self, x: f64, y: f64) -> (f64, f64) {
        let (s, c) = self.heading_deg.to_radians().sin_cos();
        (x * c + y * s, -x * s + y * c)
    }

    /// World metres → WGS84.
    pub fn to_wgs84(&self, p: [f64; 3]) -> LatLonAlt {
        let (east, north) = self.east_north(p[0], p[1]);
        let (m, n_cos) = self.radii();
        LatLonAlt {
            lat: self.origin[0] + (north / m).to_degrees(),
            lon: wrap_lon(self.origin[1] + (east / n_cos).to_degrees()),
            alt: self.origin[2] + p[2],
        }
    }

    /// WGS84 → world metres (the inverse of [`Geo::to_wgs84`] on the same tangent plane).
    pub fn to_local(&self, g: LatLonAlt) -> [f64; 3] {
        let (m, n_cos) = self.radii();
        let north = (g.lat - self.origin[0]).to_radians() * m;
        let east = wrap_lon(g.lon - self.origin[1]).to_radians() * n_cos;
        let (s, c) = self.heading_deg.to_radians().sin_cos();
        [east * c - north * s, east * s + north * c, g.alt - self.origin[2]]
    }
}

/// A longitude brought back into (-180, 180].
fn wrap_lon(lon: f64) -> f64 {
    let w = (lon + 180.0).rem_euclid(360.0) - 180.0;
    if w == -180.0 { 180.0 } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn at(lat: f64, lon: f64, heading: f64) -> Geo {
        Geo {
            origin: [lat, lon, 100.0],
            heading_deg: heading,
        }
    }

    /// On the equator the meridian radius is a(1 − e²) = 6 335 439.327 m and the prime vertical
    /// radius is a: one metre north is 1/6 335 439.327 rad = 9.043 695e-6°, one metre east
    /// 1/6 378 137 rad = 8.983 153e-6° (hand-computed).
    #[test]
    fn one_metre_at_the_equator_matches_hand_values() {
        let g = at(0.0, 0.0, 0.0);
        let north = g.to_wgs84([0.0, 1.0, 0.0]);
        assert_relative_eq!(north.lat, 9.043_695e-6, max_relative = 1e-6);
        assert_relative_eq!(north.lon, 0.0);
        let east = g.to_wgs84([1.0, 0.0, 2.5]);
        assert_relative_eq!(east.lon, 8.983_153e-6, max_relative = 1e-6);
        assert_relative_eq!(east.lat, 0.0);
        assert_relative_eq!(east.alt, 102.5);
    }

    /// At 48.5° N (Tübingen, paper 004's campus): sin²φ = 0.560 935, w = √(1 − e² sin²φ) =
    /// 0.998 120 7; M = a(1 − e²)/w³ = 6 371 293 m and N = a/w = 6 390 146 m, so 100 m east is
    /// 100/(N cos φ) rad = 1.353 154e-3° and 100 m north 8.992 80e-4° (computed by hand with a
    /// calculator, not with this code).
    #[test]
    fn east_at_mid_latitude_matches_hand_values() {
        let g = at(48.5, 9.0, 0.0);
        let p = g.to_wgs84([100.0, 0.0, 0.0]);
        assert_relative_eq!(p.lon - 9.0, 1.353_154e-3, max_relative = 1e-5);
        let q = g.to_wgs84([0.0, 100.0, 0.0]);
        assert_relative_eq!(q.lat - 48.5, 8.992_80e-4, max_relative = 1e-5);
    }

    /// Heading 90°: +y points east, +x south.
    #[test]
    fn heading_rotates_the_world_clockwise() {
        let g = at(0.0, 0.0, 90.0);
        let (e, n) = g.east_north(0.0, 1.0);
        assert_relative_eq!(e, 1.0, epsilon = 1e-12);
        assert_relative_eq!(n, 0.0, epsilon = 1e-12);
        let (e, n) = g.east_north(1.0, 0.0);
        assert_relative_eq!(e, 0.0, epsilon = 1e-12);
        assert_relative_eq!(n, -1.0, epsilon = 1e-12);
        assert!(g.to_wgs84([0.0, 10.0, 0.0]).lon > 0.0);
        assert!(g.to_wgs84([10.0, 0.0, 0.0]).lat < 0.0);
    }

    #[test]
    fn longitudes_wrap_at_the_date_line() {
        let g = at(0.0, 179.999_99, 0.0);
        let p = g.to_wgs84([10.0, 0.0, 0.0]);
        assert!(p.lon < -179.999, "{}", p.lon);
        let back = g.to_local(p);
        assert_relative_eq!(back[0], 10.0, epsilon = 1e-6);
    }

    #[test]
    fn bad_origins_are_named() {
        assert_eq!(at(90.0, 0.0, 0.0).validate(), Err(GeoError::Latitude(90.0)));
        assert_eq!(at(0.0, 181.0, 0.0).validate(), Err(GeoError::Longitude(181.0)));
        assert!(matches!(
            at(f64::NAN, 0.0, 0.0).validate(),
            Err(GeoError::NotFinite(_))
        ));
        assert_eq!(
            at(0.0, 0.0, f64::INFINITY).validate(),
            Err(GeoError::Heading(f64::INFINITY))
        );
        assert_eq!(at(48.5, 9.0, 30.0).validate(), Ok(()));
        let e = at(95.0, 0.0, 0.0).validate().unwrap_err().to_string();
        assert!(e.contains("world.geo.origin") && e.contains("95"), "{e}");
    }

    #[test]
    fn toml_keys_are_kebab_case_and_unknown_ones_refused() {
        let g: Geo = serde_json::from_str(r#"{"origin": [48.5, 9.0, 320.0], "heading-deg": 12.5}"#).unwrap();
        assert_eq!(g.heading_deg, 12.5);
        assert!(serde_json::from_str::<Geo>(r#"{"origin": [0, 0, 0], "heading": 1}"#).is_err());
    }

    proptest! {
        /// local → WGS84 → local is the identity on building-sized worlds anywhere off the poles.
        #[test]
        fn round_trip(lat in -80.0f64..80.0, lon in -180.0f64..180.0, h in -360.0f64..360.0,
                      x in -500.0f64..500.0, y in -500.0f64..500.0, z in -10.0f64..50.0) {
            let g = at(lat, lon, h);
            let back = g.to_local(g.to_wgs84([x, y, z]));
            prop_assert!((back[0] - x).abs() < 1e-6 && (back[1] - y).abs() < 1e-6 && (back[2] - z).abs() < 1e-9);
        }
    }
}
