//! The CIE standard overcast sky (Moon and Spencer 1942; CIE S 011/E:2003 sky type 16).
//!
//! Radiance depends on the zenith angle `theta` alone: `L(theta) = L_z (1 + 2 cos theta) / 3`,
//! so the horizon is a third of the zenith. Over the upper hemisphere it gives the horizontal
//! irradiance `E_h = int L cos theta dOmega = 2 pi L_z / 3 (1/2 + 2/3) = 7 pi L_z / 9`, hence
//! `L_z = 9 E_h / (7 pi)` ([`CieOvercast::from_horizontal_irradiance`]; with illuminance in lux
//! it gives the zenith luminance in cd m^-2). Below the horizon it is zero.

use crate::SkyError;

/// The CIE overcast sky, its zenith radiance per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CieOvercast {
    /// Radiance at the zenith per channel (any radiometric unit; the horizon has a third).
    pub zenith: [f64; 3],
}

impl CieOvercast {
    /// The sky with this zenith radiance per channel (finite, >= 0).
    pub fn new(zenith: [f64; 3]) -> Result<Self, SkyError> {
        if !zenith.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(SkyError::Radiance(zenith));
        }
        Ok(CieOvercast { zenith })
    }

    /// The sky that gives a horizontal surface the irradiance `e_h` per channel (finite,
    /// >= 0): zenith radiance `9 e_h / (7 pi)`.
    pub fn from_horizontal_irradiance(e_h: [f64; 3]) -> Result<Self, SkyError> {
        if !e_h.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(SkyError::Irradiance(e_h));
        }
        Ok(CieOvercast {
            zenith: e_h.map(|e| 9.0 * e / (7.0 * std::f64::consts::PI)),
        })
    }

    /// The horizontal irradiance this sky gives, `7 pi L_z / 9` per channel.
    pub fn horizontal_irradiance(&self) -> [f64; 3] {
        self.zenith.map(|l| 7.0 * std::f64::consts::PI * l / 9.0)
    }

    /// The radiance from a direction whose cosine with the zenith is `cos_theta`: zero below
    /// the horizon.
    pub fn radiance(&self, cos_theta: f64) -> [f64; 3] {
        if !(cos_theta >= 0.0) {
            return [0.0; 3];
        }
        let f = (1.0 + 2.0 * cos_theta.min(1.0)) / 3.0;
        self.zenith.map(|l| l * f)
    }
}
