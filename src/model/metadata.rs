//! How trajectories were made, as their OpenEXR file records it: one JSON
//! object in the `voltrack` text attribute ([`METADATA_ATTRIBUTE`]), written
//! by `export::exr` and read back by `io::exr`.
//!
//! The on-disk names and forms are those of the first files voltrack wrote
//! (`voltrack.resolution` as the text "256", say), so old files read and new
//! files stay byte-identical to what earlier versions wrote.

use super::GridSpec;
use crate::math::Real;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Name of the OpenEXR attribute holding the metadata.
pub const METADATA_ATTRIBUTE: &str = "voltrack";

/// The grid trajectories were tracked on.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridRecord {
    /// Voxels along x, y and z ([`GridSpec::dims`]).
    pub dims: [usize; 3],
    /// World position of the grid's lowest corner ([`GridSpec::origin`]).
    pub origin: [Real; 3],
    /// Edge length of a voxel, in the input's units.
    pub voxel_size: Real,
}

impl From<&GridSpec> for GridRecord {
    fn from(g: &GridSpec) -> Self {
        GridRecord {
            dims: g.dims,
            origin: [g.origin.x, g.origin.y, g.origin.z],
            voxel_size: g.voxel_size,
        }
    }
}

/// The metadata of a trajectories file; every field is optional, as files
/// from other tools (any RGB float EXR) carry none.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryMetadata {
    /// Voxels along the longest side of the input's bounding box.
    #[serde(
        rename = "voltrack.resolution",
        with = "text",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub resolution: Option<usize>,
    /// The grid's voxel size, in the input's units.
    #[serde(
        rename = "voltrack.voxel_size",
        with = "scientific",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub voxel_size: Option<Real>,
    /// The grid the trajectories were tracked on.
    #[serde(
        rename = "voltrack.grid",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub grid: Option<GridRecord>,
    /// Frames tracked.
    #[serde(
        rename = "voltrack.frames",
        with = "text",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub frames: Option<usize>,
    /// The tracking parameters (`params::TrackParams` as serialised).
    #[serde(
        rename = "voltrack.track",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub track: Option<serde_json::Value>,
    /// The first input frame, as messages named it.
    #[serde(
        rename = "voltrack.first_input",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub first_input: Option<String>,
    /// The refinement parameters (`params::RefineParams` as serialised),
    /// when the trajectories were refined.
    #[serde(
        rename = "voltrack.refine",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub refine: Option<serde_json::Value>,
    /// Original indices of the centers refinement removed, in removal order.
    #[serde(
        rename = "voltrack.removed",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub removed: Option<Vec<usize>>,
    /// The frame the centers were placed in and tracked from
    /// ([`super::Trajectories::reference`]), when not frame 0.
    #[serde(
        rename = "voltrack.reference",
        with = "text",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub reference: Option<usize>,
    /// The version of voltrack that wrote the file (set by the writer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub version: Option<String>,
    /// Anything else the attribute held, kept as it was.
    #[serde(flatten)]
    pub other: BTreeMap<String, serde_json::Value>,
}

impl TrajectoryMetadata {
    /// Whether the trajectories were tracked with lengths in the input's
    /// units (`TrackParams::absolute_units`; false when not recorded):
    /// refining them later takes its lengths the same way.
    pub fn absolute_units(&self) -> bool {
        self.track
            .as_ref()
            .and_then(|t| t.get("absolute_units")?.as_bool())
            .unwrap_or(false)
    }
}

/// A number stored as its decimal text ("256").
mod text {
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<usize>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => s.serialize_str(&v.to_string()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<usize>, D::Error> {
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::String(t) => t.trim().parse().map(Some).map_err(D::Error::custom),
            serde_json::Value::Number(n) => n
                .as_u64()
                .map(|n| Some(n as usize))
                .ok_or_else(|| D::Error::custom("not a count")),
            serde_json::Value::Null => Ok(None),
            other => Err(D::Error::custom(format!("not a count: {other}"))),
        }
    }
}

/// A float stored as its scientific text ("3.90625e-3"), every digit kept.
mod scientific {
    use crate::math::Real;
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<Real>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => s.serialize_str(&format!("{v:e}")),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Real>, D::Error> {
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::String(t) => t.trim().parse().map(Some).map_err(D::Error::custom),
            serde_json::Value::Number(n) => Ok(n.as_f64()),
            serde_json::Value::Null => Ok(None),
            other => Err(D::Error::custom(format!("not a number: {other}"))),
        }
    }
}
