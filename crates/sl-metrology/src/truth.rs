//! The truth description: which features a scanned object has, their nominal sizes and,
//! when known, their nominal positions. Serialised as JSON (`docs/metrology.md`).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::MetrologyError;

/// Default half-width of a feature's selection region (mm): the points within this distance
/// of the nominal (or found) surface belong to the feature. 2 mm is 40 times the 0.05 mm
/// probing target, so every point a scanner measures roughly right is kept, while stray
/// points of other surfaces a few millimetres away are not.
pub const DEFAULT_SELECT_MM: f64 = 2.0;

fn default_select() -> f64 {
    DEFAULT_SELECT_MM
}

/// A sphere of known radius (VDI/VDE 2634 part 2: the probing-error artefact).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphereSpec {
    /// Name, unique in the description (reports and errors use it).
    pub name: String,
    /// Calibrated radius (mm).
    pub radius_mm: f64,
    /// Nominal centre in the cloud's frame (mm), when known. Without it the sphere is found
    /// in the cloud by RANSAC with the known radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre_mm: Option<Point3<f64>>,
    /// Points within this distance of the sphere surface (nominal, or found) are the
    /// sphere's points (mm).
    #[serde(default = "default_select")]
    pub select_mm: f64,
}

/// Two spheres of a description whose centre distance is calibrated (the dumbbell or ball
/// bar of VDI/VDE 2634 part 2: the sphere-spacing error).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpherePairSpec {
    /// Name, unique in the description.
    pub name: String,
    /// Names of the two [`SphereSpec`]s.
    pub spheres: [String; 2],
    /// Calibrated distance of their centres (mm).
    pub centre_distance_mm: f64,
}

/// A nominal plane: the points `p` with `normal · p = offset_mm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlaneNominal {
    /// Normal (normalised on use; its sign sets the sign of the signed distances).
    pub normal: Vector3<f64>,
    /// Signed distance of the plane from the origin along `normal` (mm).
    pub offset_mm: f64,
}

/// A flat surface (VDI/VDE 2634 part 2: the flatness artefact).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneSpec {
    /// Name, unique in the description.
    pub name: String,
    /// Nominal plane, when known. Without it the plane with the most points is found in the
    /// cloud by RANSAC.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<PlaneNominal>,
    /// Points within this distance of the plane (nominal, or found) are the plane's points
    /// (mm). The plane is unbounded: crop the cloud to the plate when other surfaces cross it.
    #[serde(default = "default_select")]
    pub select_mm: f64,
}

/// One feature of a [`Truth`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Feature {
    /// A sphere.
    Sphere(SphereSpec),
    /// A pair of spheres with a calibrated centre distance.
    SpherePair(SpherePairSpec),
    /// A plane.
    Plane(PlaneSpec),
}

impl Feature {
    /// The feature's name.
    pub fn name(&self) -> &str {
        match self {
            Self::Sphere(s) => &s.name,
            Self::SpherePair(s) => &s.name,
            Self::Plane(s) => &s.name,
        }
    }
}

/// What a scanned object is known to be: its features, in millimetres, in the frame of the
/// cloud that will be evaluated.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Truth {
    /// Free text: the artefact, its calibration certificate, the frame.
    #[serde(default)]
    pub description: String,
    /// The features.
    pub features: Vec<Feature>,
}

impl Truth {
    /// An empty description.
    pub fn new(description: impl Into<String>) -> Self {
        Self {
            description: description.into(),
            features: Vec::new(),
        }
    }

    /// Adds a feature.
    pub fn with(mut self, feature: Feature) -> Self {
        self.features.push(feature);
        self
    }

    /// The sphere named `name`.
    pub fn sphere(&self, name: &str) -> Option<&SphereSpec> {
        self.features.iter().find_map(|f| match f {
            Feature::Sphere(s) if s.name == name => Some(s),
            _ => None,
        })
    }

    /// Checks the description: unique non-empty names, positive finite sizes and selection
    /// widths, non-zero normals, pairs naming two different spheres of the description.
    ///
    /// # Errors
    /// [`MetrologyError::InvalidTruth`] naming the first feature at fault.
    pub fn validate(&self) -> Result<(), MetrologyError> {
        if self.features.is_empty() {
            return Err(MetrologyError::truth("truth", "no feature to measure"));
        }
        let mut names = HashSet::new();
        let positive = |name: &str, what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(MetrologyError::truth(
                    name,
                    format!("{what} {v} is not a positive length"),
                ))
            }
        };
        let finite = |name: &str, what: &str, v: &[f64]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(MetrologyError::truth(
                    name,
                    format!("{what} {v:?} is not finite"),
                ))
            }
        };
        for f in &self.features {
            let name = f.name();
            if name.is_empty() {
                return Err(MetrologyError::truth(name, "the name is empty"));
            }
            if !names.insert(name) {
                return Err(MetrologyError::truth(name, "two features have this name"));
            }
            match f {
                Feature::Sphere(s) => {
                    positive(name, "radius_mm", s.radius_mm)?;
                    positive(name, "select_mm", s.select_mm)?;
                    if let Some(c) = &s.centre_mm {
                        finite(name, "centre_mm", c.coords.as_slice())?;
                    }
                }
                Feature::Plane(p) => {
                    positive(name, "select_mm", p.select_mm)?;
                    if let Some(n) = &p.nominal {
                        finite(name, "normal", n.normal.as_slice())?;
                        finite(name, "offset_mm", &[n.offset_mm])?;
                        if n.normal.norm() <= 0.0 {
                            return Err(MetrologyError::truth(name, "the normal is zero"));
                        }
                    }
                }
                Feature::SpherePair(p) => {
                    positive(name, "centre_distance_mm", p.centre_distance_mm)?;
                    if p.spheres[0] == p.spheres[1] {
                        return Err(MetrologyError::truth(
                            name,
                            format!("both spheres are `{}`", p.spheres[0]),
                        ));
                    }
                    for s in &p.spheres {
                        if self.sphere(s).is_none() {
                            return Err(MetrologyError::truth(
                                name,
                                format!("no sphere named `{s}` in the description"),
                            ));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Parses a description from JSON text and validates it.
    ///
    /// # Errors
    /// [`MetrologyError::Json`] (path `<string>`) or [`MetrologyError::InvalidTruth`].
    pub fn from_json(text: &str) -> Result<Self, MetrologyError> {
        Self::parse(text, Path::new("<string>"))
    }

    fn parse(text: &str, path: &Path) -> Result<Self, MetrologyError> {
        let truth: Self = serde_json::from_str(text).map_err(|source| MetrologyError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        truth.validate()?;
        Ok(truth)
    }

    /// Pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // A `Truth` has only strings, numbers, arrays and maps with string keys: serialising
        // it cannot fail; `null` would be an honest (if useless) fallback.
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "null".to_owned())
    }

    /// Reads and validates a truth file.
    ///
    /// # Errors
    /// [`MetrologyError::Io`], [`MetrologyError::Json`] or [`MetrologyError::InvalidTruth`],
    /// naming the file or the feature.
    pub fn load(path: &Path) -> Result<Self, MetrologyError> {
        let text = std::fs::read_to_string(path).map_err(|source| MetrologyError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Writes the description as pretty-printed JSON.
    ///
    /// # Errors
    /// [`MetrologyError::Io`] naming the file.
    pub fn save(&self, path: &Path) -> Result<(), MetrologyError> {
        std::fs::write(path, self.to_json()).map_err(|source| MetrologyError::Io {
            path: PathBuf::from(path),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full() -> Truth {
        Truth::new("dumbbell and plate")
            .with(Feature::Sphere(SphereSpec {
                name: "left".to_owned(),
                radius_mm: 25.0,
                centre_mm: Some(Point3::new(-60.0, 0.1, 450.25)),
                select_mm: 1.5,
            }))
            .with(Feature::Sphere(SphereSpec {
                name: "right".to_owned(),
                radius_mm: 25.0,
                centre_mm: None,
                select_mm: DEFAULT_SELECT_MM,
            }))
            .with(Feature::SpherePair(SpherePairSpec {
                name: "bar".to_owned(),
                spheres: ["left".to_owned(), "right".to_owned()],
                centre_distance_mm: 120.0,
            }))
            .with(Feature::Plane(PlaneSpec {
                name: "plate".to_owned(),
                nominal: Some(PlaneNominal {
                    normal: Vector3::new(0.1, 0.2, -1.0),
                    offset_mm: -400.0 / 3.0,
                }),
                select_mm: 0.5,
            }))
    }

    /// JSON written and read back is the same description, bit for bit (`serde_json` prints
    /// the shortest decimal that round-trips an `f64`); so is a file.
    #[test]
    fn json_round_trip() {
        let t = full();
        assert_eq!(Truth::from_json(&t.to_json()).unwrap(), t);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("truth.json");
        t.save(&path).unwrap();
        assert_eq!(Truth::load(&path).unwrap(), t);
    }

    /// The documented file shape (docs/metrology.md): tagged features, points and vectors as
    /// arrays, `select_mm` optional.
    #[test]
    fn hand_written_file_parses() {
        let text = r#"{
          "description": "ball bar, certificate 2026-01",
          "features": [
            {"type": "sphere", "name": "a", "radius_mm": 12.7},
            {"type": "sphere", "name": "b", "radius_mm": 12.7, "centre_mm": [1, 2, 3], "select_mm": 0.5},
            {"type": "sphere_pair", "name": "bar", "spheres": ["a", "b"], "centre_distance_mm": 200.02},
            {"type": "plane", "name": "plate", "nominal": {"normal": [0, 0, -1], "offset_mm": -400}}
          ]
        }"#;
        let t = Truth::from_json(text).unwrap();
        assert_eq!(t.features.len(), 4);
        let a = t.sphere("a").unwrap();
        assert_eq!((a.centre_mm, a.select_mm), (None, DEFAULT_SELECT_MM));
        assert_eq!(
            t.sphere("b").unwrap().centre_mm,
            Some(Point3::new(1.0, 2.0, 3.0))
        );
    }

    /// Inconsistent descriptions are refused naming the feature; malformed JSON names the file.
    #[test]
    fn invalid_descriptions_are_refused() {
        let mut t = full();
        if let Some(Feature::SpherePair(p)) = t.features.get_mut(2) {
            p.spheres[1] = "middle".to_owned();
        }
        let err = t.validate().unwrap_err().to_string();
        assert!(err.contains("bar") && err.contains("middle"), "{err}");
        let mut t = full();
        t.features.push(t.features[0].clone());
        assert!(t.validate().unwrap_err().to_string().contains("left"));
        let mut t = full();
        if let Some(Feature::Sphere(s)) = t.features.get_mut(0) {
            s.radius_mm = -1.0;
        }
        assert!(t.validate().unwrap_err().to_string().contains("radius_mm"));
        assert!(Truth::new("empty").validate().is_err());
        let err = Truth::from_json("{\"features\": [{\"type\": \"cone\"}]}").unwrap_err();
        assert!(matches!(err, MetrologyError::Json { .. }), "{err}");
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope.json");
        assert!(
            Truth::load(&missing)
                .unwrap_err()
                .to_string()
                .contains("nope.json")
        );
    }
}
