//! Reading center trajectories back from OpenEXR.

use crate::error::{Error, Result};
use crate::math::Point3;
use crate::model::{Trajectories, TrajectoryMetadata, METADATA_ATTRIBUTE};
use exr::meta::attribute::AttributeValue;
use exr::prelude::*;
use std::path::Path;

/// Reads trajectories written by `voltrack track` (or any RGB float EXR:
/// width = centers, height = frames) and the metadata of its `voltrack`
/// attribute (empty when it has none).
pub fn read_trajectories_exr(path: &Path) -> Result<(Trajectories, TrajectoryMetadata)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("R")
        .required("G")
        .required("B")
        .collect_pixels(
            |size: Vec2<usize>, _| {
                (
                    size.width(),
                    vec![Point3::origin(); size.width() * size.height()],
                )
            },
            |(w, px): &mut (usize, Vec<Point3>), p: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                px[p.y() * *w + p.x()] = Point3::new(r as f64, g as f64, b as f64);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| Error::parse(path, None, format!("not a readable RGB OpenEXR image: {e}")))?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let (_, positions) = &layer.channel_data.pixels;
    if let Some(i) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Error::parse(
            path,
            None,
            format!("center {} of frame {} is not finite", i % width, i / width),
        ));
    }
    let traj = Trajectories {
        frames: height,
        centers: width,
        positions: positions.clone(),
        reference: 0,
    };
    let mut metadata = TrajectoryMetadata::default();
    let meta = layer.attributes.other.iter().chain(&image.attributes.other);
    for (name, value) in meta {
        if name != METADATA_ATTRIBUTE {
            continue;
        }
        let AttributeValue::Text(text) = value else {
            continue;
        };
        metadata = serde_json::from_str(&text.to_string()).map_err(|e| {
            Error::parse(
                path,
                None,
                format!("the voltrack attribute is not voltrack's metadata: {e}"),
            )
        })?;
    }
    let mut traj = traj;
    if let Some(r) = metadata.reference {
        if r >= traj.frames {
            return Err(Error::parse(
                path,
                None,
                format!("its reference frame {r} is past its {} frames", traj.frames),
            ));
        }
        traj.reference = r;
    }
    Ok((traj, metadata))
}
