//! The images an E57 file carries (ASTM E2807's `images2D`): each one's name, model (pinhole,
//! spherical, cylindrical, or a visual reference shown with the data but not placed), size,
//! format (JPEG or PNG), pose, and its bytes on demand. A projected image is preferred to the
//! visual reference of the same entry.

use myriad_core::{Error, Result};
use std::path::Path;

/// How an image maps the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Model {
    /// Focal lengths and principal point, in pixels (E57's focal length over its pixel size).
    Pinhole {
        focal: [f64; 2],
        principal: [f64; 2],
    },
    Spherical,
    Cylindrical,
    /// A visual reference: not placed.
    Reference,
}

#[derive(Debug, Clone)]
pub struct E57Image {
    pub name: String,
    pub model: Model,
    pub width: u32,
    pub height: u32,
    /// "jpeg" or "png".
    pub format: &'static str,
    /// Rotation (a quaternion, w x y z) and translation.
    pub pose: Option<([f64; 4], [f64; 3])>,
    blob: e57::Blob,
}

impl E57Image {
    /// The image's size in the file, bytes.
    pub fn bytes(&self) -> u64 {
        self.blob.length
    }

    pub fn model_name(&self) -> &'static str {
        match self.model {
            Model::Pinhole { .. } => "pinhole",
            Model::Spherical => "spherical",
            Model::Cylindrical => "cylindrical",
            Model::Reference => "visual reference",
        }
    }
}

fn format_of(f: &e57::ImageFormat) -> &'static str {
    match f {
        e57::ImageFormat::Jpeg => "jpeg",
        e57::ImageFormat::Png => "png",
    }
}

/// The images of the E57 file at `path`.
pub fn images(path: &Path) -> Result<Vec<E57Image>> {
    let r = e57::E57Reader::from_file(path)
        .map_err(|e| Error::unsupported(path, format!("E57: {e}")))?;
    let mut out = Vec::new();
    for (i, im) in r.images().into_iter().enumerate() {
        let name = (im.name.clone()).unwrap_or_else(|| format!("image {}", i + 1));
        let pose = im.transform.as_ref().map(|t| {
            let (q, v) = (&t.rotation, &t.translation);
            ([q.w, q.x, q.y, q.z], [v.x, v.y, v.z])
        });
        let (model, width, height, blob) = match (&im.projection, &im.visual_reference) {
            (Some(e57::Projection::Pinhole(p)), _) => {
                let pp = &p.properties;
                let model = Model::Pinhole {
                    focal: [
                        pp.focal_length / pp.pixel_width,
                        pp.focal_length / pp.pixel_height,
                    ],
                    principal: [pp.principal_x, pp.principal_y],
                };
                (model, pp.width, pp.height, p.blob.clone())
            }
            (Some(e57::Projection::Spherical(s)), _) => (
                Model::Spherical,
                s.properties.width,
                s.properties.height,
                s.blob.clone(),
            ),
            (Some(e57::Projection::Cylindrical(c)), _) => (
                Model::Cylindrical,
                c.properties.width,
                c.properties.height,
                c.blob.clone(),
            ),
            (None, Some(v)) => (
                Model::Reference,
                v.properties.width,
                v.properties.height,
                v.blob.clone(),
            ),
            (None, None) => continue,
        };
        out.push(E57Image {
            name,
            model,
            width,
            height,
            format: format_of(&blob.format),
            pose: pose.filter(|_| model != Model::Reference),
            blob: blob.data,
        });
    }
    Ok(out)
}

/// The bytes of `image` of the E57 file at `path` (at most `max`).
pub fn image_bytes(path: &Path, image: &E57Image, max: u64) -> Result<Vec<u8>> {
    if image.blob.length > max {
        return Err(Error::unsupported(
            path,
            format!(
                "image \"{}\" of {} bytes: more than {max}",
                image.name, image.blob.length
            ),
        ));
    }
    let mut r = e57::E57Reader::from_file(path)
        .map_err(|e| Error::unsupported(path, format!("E57: {e}")))?;
    let mut out = Vec::with_capacity(image.blob.length as usize);
    r.blob(&image.blob, &mut out)
        .map_err(|e| Error::unsupported(path, format!("image \"{}\": {e}", image.name)))?;
    Ok(out)
}
