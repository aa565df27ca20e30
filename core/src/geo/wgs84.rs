//! WGS84 geodetic coordinates and local tangent (NED) frames on the ellipsoid.

use super::{finite, GeoError};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// WGS84 semi-major axis (m).
const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared.
const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// A WGS84 position: latitude and longitude in degrees, height above the ellipsoid in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geodetic {
    /// Latitude, degrees north, in [-90, 90].
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
    /// Height above the ellipsoid (m). Only differences matter inside one flight.
    pub alt_m: f64,
}

impl Geodetic {
    /// Builds a checked position: finite values and a latitude within [-90, 90].
    pub fn new(lat_deg: f64, lon_deg: f64, alt_m: f64) -> Result<Self, GeoError> {
        finite("latitude", lat_deg)?;
        finite("longitude", lon_deg)?;
        finite("altitude", alt_m)?;
        if !(-90.0..=90.0).contains(&lat_deg) {
            return Err(GeoError::InvalidParameter {
                what: "latitude",
                value: lat_deg,
            });
        }
        Ok(Self {
            lat_deg,
            lon_deg,
            alt_m,
        })
    }

    /// Earth-centred, earth-fixed coordinates (m).
    pub fn to_ecef(&self) -> Vector3<f64> {
        let (slat, clat) = self.lat_deg.to_radians().sin_cos();
        let (slon, clon) = self.lon_deg.to_radians().sin_cos();
        let n = WGS84_A / (1.0 - WGS84_E2 * slat * slat).sqrt();
        Vector3::new(
            (n + self.alt_m) * clat * clon,
            (n + self.alt_m) * clat * slon,
            (n * (1.0 - WGS84_E2) + self.alt_m) * slat,
        )
    }

    /// Inverse of [`Geodetic::to_ecef`]: fixed-point iteration on latitude, converged to far
    /// below a millimetre for any point within a few hundred kilometres of the surface.
    pub fn from_ecef(p: &Vector3<f64>) -> Self {
        let lon = p.y.atan2(p.x);
        let r_xy = p.x.hypot(p.y);
        let mut lat = p.z.atan2(r_xy * (1.0 - WGS84_E2));
        for _ in 0..8 {
            let slat = lat.sin();
            let n = WGS84_A / (1.0 - WGS84_E2 * slat * slat).sqrt();
            let next = (p.z + WGS84_E2 * n * slat).atan2(r_xy);
            let done = (next - lat).abs() < 1e-15;
            lat = next;
            if done {
                break;
            }
        }
        let (slat, clat) = lat.sin_cos();
        // Robust everywhere, including near the poles where r_xy / cos(lat) is ill-conditioned.
        let alt = r_xy * clat + p.z * slat - WGS84_A * (1.0 - WGS84_E2 * slat * slat).sqrt();
        Self {
            lat_deg: lat.to_degrees(),
            lon_deg: lon.to_degrees(),
            alt_m: alt,
        }
    }
}

/// A local north-east-down frame tangent to the ellipsoid at an origin.
///
/// Exact (through ECEF), so round trips are limited only by floating point: far better than
/// 1 cm within 10 km of the origin.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalTangentFrame {
    origin: Geodetic,
    origin_ecef: Vector3<f64>,
    /// Rows are the north, east and down unit vectors expressed in ECEF.
    ecef_to_ned: Matrix3<f64>,
}

impl LocalTangentFrame {
    /// A frame with its origin at `origin` (the origin's altitude is the frame's down = 0).
    pub fn new(origin: Geodetic) -> Self {
        let (slat, clat) = origin.lat_deg.to_radians().sin_cos();
        let (slon, clon) = origin.lon_deg.to_radians().sin_cos();
        let ecef_to_ned = Matrix3::new(
            -slat * clon,
            -slat * slon,
            clat,
            -slon,
            clon,
            0.0,
            -clat * clon,
            -clat * slon,
            -slat,
        );
        Self {
            origin,
            origin_ecef: origin.to_ecef(),
            ecef_to_ned,
        }
    }

    /// The frame's origin.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// North, east, down (m) of a geodetic position in this frame.
    pub fn to_ned(&self, p: &Geodetic) -> Vector3<f64> {
        self.ecef_to_ned * (p.to_ecef() - self.origin_ecef)
    }

    /// The geodetic position of a point given in this frame.
    pub fn to_geodetic(&self, ned: &Vector3<f64>) -> Geodetic {
        Geodetic::from_ecef(&(self.origin_ecef + self.ecef_to_ned.transpose() * ned))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn origin_maps_to_zero() {
        let f = LocalTangentFrame::new(Geodetic::new(47.67, 9.27, 400.0).unwrap());
        assert!(f.to_ned(&f.origin()).norm() < 1e-9);
    }

    #[test]
    fn one_degree_of_latitude_is_about_111_km() {
        let f = LocalTangentFrame::new(Geodetic::new(0.0, 0.0, 0.0).unwrap());
        let p = f.to_ned(&Geodetic::new(1.0, 0.0, 0.0).unwrap());
        // Meridian arc length of the first degree from the equator on WGS84: 110574.4 m.
        assert!((p.x - 110_574.4).abs() < 20.0, "north {}", p.x);
        assert!(p.y.abs() < 1e-6);
        // The ellipsoid drops away below the tangent plane.
        assert!(p.z > 900.0);
    }

    #[test]
    fn east_is_east_and_down_is_down() {
        let f = LocalTangentFrame::new(Geodetic::new(47.0, 9.0, 0.0).unwrap());
        let e = f.to_ned(&Geodetic::new(47.0, 9.001, 0.0).unwrap());
        assert!(e.y > 70.0 && e.y < 80.0, "{e}");
        let up = f.to_ned(&Geodetic::new(47.0, 9.0, 100.0).unwrap());
        assert!((up.z + 100.0).abs() < 1e-6 && up.x.abs() < 1e-6);
    }

    #[test]
    fn rejects_bad_latitude() {
        assert!(Geodetic::new(91.0, 0.0, 0.0).is_err());
        assert!(Geodetic::new(f64::NAN, 0.0, 0.0).is_err());
    }

    proptest! {
        #[test]
        fn ned_round_trip_sub_millimetre_within_10_km(
            lat in -85.0f64..85.0, lon in -180.0f64..180.0,
            n in -10_000.0f64..10_000.0, e in -10_000.0f64..10_000.0, d in -500.0f64..500.0,
        ) {
            let f = LocalTangentFrame::new(Geodetic::new(lat, lon, 30.0).unwrap());
            let ned = Vector3::new(n, e, d);
            let back = f.to_ned(&f.to_geodetic(&ned));
            prop_assert!((back - ned).norm() < 1e-3, "{} vs {}", back, ned);
        }

        #[test]
        fn ecef_round_trip(lat in -89.9f64..89.9, lon in -180.0f64..180.0, alt in -100.0f64..10_000.0) {
            let g = Geodetic::new(lat, lon, alt).unwrap();
            let back = Geodetic::from_ecef(&g.to_ecef());
            prop_assert!((back.lat_deg - lat).abs() < 1e-10);
            prop_assert!((back.alt_m - alt).abs() < 1e-4);
        }
    }
}
