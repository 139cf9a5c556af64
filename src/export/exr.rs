//! OpenEXR output: center trajectories and vertex-animation textures.
//!
//! Both are one RGB float32 image, R, G, B = x, y, z in the input's units,
//! ZIP-compressed (lossless): trajectories one column per center and one row
//! per frame, textures as [`super::vat`] lays them out. Our
//! metadata travel as one JSON text attribute, `voltrack`: the exr crate keeps
//! extra attributes in a `HashMap` and writes them in its random order, so one
//! attribute is what keeps the file bit-identical from run to run.

use crate::error::{Error, Result};
use crate::files::write_atomic;
use crate::math::Point3;
use crate::model::{Trajectories, TrajectoryMetadata, METADATA_ATTRIBUTE};
use exr::meta::attribute::{AttributeValue, Text};
use exr::prelude::*;
use std::io::{Seek, Write};
use std::path::Path;

/// Writes `traj` (width = centers, height = frames) with `metadata` (its
/// version set to this tool's) in the header.
pub fn write_trajectories_exr(
    path: &Path,
    traj: &Trajectories,
    metadata: &TrajectoryMetadata,
) -> Result<()> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    trajectory_image(path, traj, metadata)?.encode(&mut bytes)?;
    write_atomic(path, |w| w.write_all(bytes.get_ref()))
}

/// [`write_trajectories_exr`] into a writer of the caller's, `name`d so in
/// errors. What was written before an error stays written.
pub fn write_trajectories_exr_to(
    w: &mut (impl Write + Seek),
    name: &str,
    traj: &Trajectories,
    metadata: &TrajectoryMetadata,
) -> Result<()> {
    trajectory_image(Path::new(name), traj, metadata)?.encode(w)
}

/// The image of `traj` with `metadata`, `path` naming it in errors.
fn trajectory_image<'a>(
    path: &'a Path,
    traj: &'a Trajectories,
    metadata: &TrajectoryMetadata,
) -> Result<PointImage<'a, impl Fn(usize, usize) -> Point3 + Sync + 'a>> {
    let meta = match serde_json::to_value(metadata).map_err(|e| Error::write(path, e))? {
        serde_json::Value::Object(map) => map,
        _ => unreachable!("a struct serialises to an object"),
    };
    Ok(PointImage {
        path,
        name: "trajectories",
        width: traj.centers,
        height: traj.frames,
        pixel: |x: usize, y: usize| traj.get(y, x),
        meta,
    })
}

/// An OpenEXR file of `width` × `height` points, `pixel(x, y)` each, with
/// `meta` as its metadata attribute; `path` names it in errors.
pub(super) struct PointImage<'a, F> {
    pub path: &'a Path,
    pub name: &'a str,
    pub width: usize,
    pub height: usize,
    pub pixel: F,
    pub meta: serde_json::Map<String, serde_json::Value>,
}

impl<F: Fn(usize, usize) -> Point3 + Sync> PointImage<'_, F> {
    /// The file written into `w` as it is encoded: straight into a file that
    /// can seek (the format's offset tables are filled in after the blocks),
    /// through memory into one that cannot (a pipe). Returns its length in
    /// bytes.
    pub(super) fn stream(self, w: &mut (impl Write + Seek)) -> Result<u64> {
        let Ok(start) = w.stream_position() else {
            let (path, mut bytes) = (self.path, std::io::Cursor::new(Vec::new()));
            self.encode(&mut bytes)?;
            w.write_all(bytes.get_ref())
                .map_err(|e| Error::write(path, e))?;
            return Ok(bytes.get_ref().len() as u64);
        };
        let mut out = Extent {
            inner: w,
            position: start,
            end: start,
        };
        self.encode(&mut out)?;
        Ok(out.end - start)
    }

    fn encode(self, w: &mut (impl Write + Seek)) -> Result<()> {
        let PointImage {
            path,
            name,
            width,
            height,
            pixel,
            mut meta,
        } = self;
        if width == 0 || height == 0 {
            return Err(Error::InvalidInput(format!(
                "nothing to write to {}: {width} × {height} points",
                path.display()
            )));
        }
        if width >= i32::MAX as usize / 2 || height >= i32::MAX as usize / 2 {
            return Err(Error::InvalidInput(format!(
                "{width} × {height} is beyond what OpenEXR can store"
            )));
        }
        // Metadata carried over from an older file (`voltrack refine` passes its
        // input's on) never claims that file's version.
        meta.insert("version".into(), env!("CARGO_PKG_VERSION").into());
        let json = ascii_json(&serde_json::Value::Object(meta).to_string());
        let mut layer_attributes = LayerAttributes::named(name);
        layer_attributes.software_name = Some(Text::new_or_panic(concat!(
            "voltrack ",
            env!("CARGO_PKG_VERSION")
        )));
        layer_attributes.other.insert(
            Text::new_or_panic(METADATA_ATTRIBUTE),
            AttributeValue::Text(Text::new_or_panic(&json)),
        );
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let q = pixel(p.x(), p.y());
            (q.x as f32, q.y as f32, q.z as f32)
        });
        let layer = Layer::new(
            (width, height),
            layer_attributes,
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        // Sequential compression: block order, hence bytes, independent of
        // threads; and the blocks are asked for in order, row after row.
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_buffered(w)
            .map_err(|e| Error::write(path, e))
    }
}

/// A writer that knows how far what was written into it reaches, though
/// the writing seeks back and forth. It counts rather than asks the file,
/// since asking flushes a `BufWriter`.
struct Extent<'a, W> {
    inner: &'a mut W,
    position: u64,
    end: u64,
}

impl<W: Write> Write for Extent<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.position += n as u64;
        self.end = self.end.max(self.position);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Seek> Seek for Extent<'_, W> {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.position = self.inner.seek(to)?;
        Ok(self.position)
    }
}

/// JSON with every non-ASCII character escaped (`\uXXXX`, surrogate pairs
/// beyond the BMP): EXR text attributes hold Latin-1 only, and escaped JSON
/// parses back to the same value.
fn ascii_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{u:04x}"));
            }
        }
    }
    out
}
