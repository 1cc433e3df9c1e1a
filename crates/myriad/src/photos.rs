//! `myriad photos DATASET`: the photos and panoramas kept with a dataset (`myriad_measure::photos`:
//! `NAME.photos.json` and the images in `NAME.photos/`): list them, add an E57 file's images or a
//! Potree panorama list (`coordinates.txt`), clear them. `render --photo N` draws the view from
//! one; both viewers show them at their positions.

use anyhow::{Result, anyhow, bail};
use clap::Args;
use myriad_measure::photos::{self, Kind, Photo, Pose};
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct PhotosArgs {
    /// The dataset (.myr) the photos are kept with (NAME.photos.json, the images in NAME.photos/)
    dataset: PathBuf,
    /// Add the images of an E57 file (pinhole and spherical ones placed by their poses, a
    /// visual reference listed, not placed) or of a Potree panorama list (coordinates.txt: file,
    /// time, x, y, z, course, pitch, roll; the images beside it); repeatable
    #[arg(long, value_name = "FILE")]
    add: Vec<PathBuf>,
    /// Remove every photo first
    #[arg(long)]
    clear: bool,
    /// Print the list as its JSON
    #[arg(long)]
    json: bool,
}

/// The most bytes one image may have.
const MAX_IMAGE: u64 = 512 << 20;

/// The photos kept with `dataset` (none: empty); an error names the file and the member.
pub fn load(dataset: &Path) -> Result<Vec<Photo>> {
    let list = photos::sidecar_for(dataset);
    match std::fs::read_to_string(&list) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(e) => Err(anyhow!("{}: {e}", list.display())),
        Ok(t) => photos::parse(&t).map_err(|e| anyhow!("{}: {e}", list.display())),
    }
}

/// Photo `n` (from 1) of `dataset`, with its image's path.
pub fn photo(dataset: &Path, n: usize) -> Result<(Photo, PathBuf)> {
    let all = load(dataset)?;
    let p = (n.checked_sub(1).and_then(|i| all.get(i)).cloned()).ok_or_else(|| {
        anyhow!(
            "--photo {n}: {} keeps {} photos (`myriad photos {}` lists them)",
            dataset.display(),
            all.len(),
            dataset.display()
        )
    })?;
    let file = photos::folder_for(dataset).join(&p.file);
    Ok((p, file))
}

fn describe(i: usize, p: &Photo) -> String {
    let place = match p.pose {
        Some(Pose { position: q, .. }) => format!("at {:.3}, {:.3}, {:.3}", q[0], q[1], q[2]),
        None => "not placed (no pose)".into(),
    };
    format!(
        "photo {} \"{}\": {} {}x{}, {place} ({})",
        i + 1,
        p.name,
        p.kind_name(),
        p.width,
        p.height,
        p.file
    )
}

pub fn run(a: PhotosArgs) -> Result<()> {
    if !a.dataset.is_file() {
        bail!("{}: no such dataset", a.dataset.display());
    }
    let list = photos::sidecar_for(&a.dataset);
    let folder = photos::folder_for(&a.dataset);
    let mut all = if a.clear {
        Vec::new()
    } else {
        load(&a.dataset)?
    };
    let before = all.len();
    for f in &a.add {
        myriad_io::atomic::refuse_input_as_output(&list, &[f])?;
        let added = if is_e57(f) {
            from_e57(f, &folder, all.len())?
        } else {
            from_potree(f, &folder, all.len())?
        };
        all.extend(added);
    }
    if all.len() > photos::MAX_PHOTOS {
        bail!("more than {} photos", photos::MAX_PHOTOS);
    }
    if a.clear || all.len() != before {
        let text = photos::to_text(&all);
        myriad_measure::files::write_atomic(&list, true, |w| w.write_all(text.as_bytes()))?;
    }
    if a.json {
        print!("{}", photos::to_text(&all));
        return Ok(());
    }
    println!("{}: {} photos", list.display(), all.len());
    for (i, p) in all.iter().enumerate() {
        println!("{}", describe(i, p));
    }
    Ok(())
}

fn is_e57(f: &Path) -> bool {
    let mut magic = [0u8; 8];
    std::fs::File::open(f)
        .and_then(|mut h| std::io::Read::read_exact(&mut h, &mut magic))
        .is_ok_and(|_| &magic == b"ASTM-E57")
}

/// A name for an image in `folder` that no file has yet (from photo `n`'s number, from 0, up),
/// so that no image a list names is written over.
fn image_name(folder: &Path, n: usize, ext: &str) -> String {
    (n + 1..)
        .map(|k| format!("{k}.{ext}"))
        .find(|name| !folder.join(name).exists())
        .expect("a free name")
}

/// `p` as the list will hold it: read back through the list's own checks (an E57 image of no
/// size, a pixel size of 0, a rotation of zeros), the file and the image named on failure.
fn checked(p: Photo, from: &Path) -> Result<Photo> {
    Photo::from_json(&p.to_json(), "photo")
        .map_err(|e| anyhow!("{}: image \"{}\": {e}", from.display(), p.name))
}

fn from_e57(f: &Path, folder: &Path, first: usize) -> Result<Vec<Photo>> {
    let images = myriad_io::e57_images::images(f)?;
    if images.is_empty() {
        bail!("{}: the E57 file carries no image", f.display());
    }
    // Every entry checked before any image is written.
    let mut out = Vec::new();
    for im in &images {
        let kind = match im.model {
            myriad_io::e57_images::Model::Pinhole { focal, principal } => {
                Kind::Pinhole { focal, principal }
            }
            myriad_io::e57_images::Model::Spherical => Kind::Spherical,
            // Shown with the data, not placed (a cylindrical model is not drawn from).
            _ => Kind::Reference,
        };
        let pose = (im.pose.filter(|_| kind != Kind::Reference))
            .map(|(rotation, position)| Pose { position, rotation });
        let file = if im.format == "png" { "png" } else { "jpg" }.to_string();
        out.push(checked(
            Photo {
                name: im.name.clone(),
                kind,
                width: im.width,
                height: im.height,
                file,
                pose,
            },
            f,
        )?);
    }
    std::fs::create_dir_all(folder).map_err(|e| anyhow!("{}: {e}", folder.display()))?;
    for (k, (im, p)) in images.iter().zip(&mut out).enumerate() {
        let bytes = myriad_io::e57_images::image_bytes(f, im, MAX_IMAGE)?;
        let name = image_name(folder, first + k, &p.file);
        myriad_measure::files::write_atomic(&folder.join(&name), false, |w| w.write_all(&bytes))?;
        p.file = name;
    }
    Ok(out)
}

fn from_potree(f: &Path, folder: &Path, first: usize) -> Result<Vec<Photo>> {
    let text = crate::measure::read_text(f, photos::MAX_BYTES, "a panorama list")?;
    let dir = f.parent().unwrap_or(Path::new("."));
    let size = |name: &str| image::image_dimensions(dir.join(name)).ok();
    let set = photos::potree_panoramas(&text, size).map_err(|e| anyhow!("{}: {e}", f.display()))?;
    if set.is_empty() {
        bail!("{}: no panorama listed", f.display());
    }
    let mut out = Vec::new();
    for p in set {
        let mut p = p;
        // (The list's names hold no folder: the image's own name is checked apart.)
        let own = std::mem::replace(&mut p.file, "image".into());
        let mut p = checked(p, f)?;
        p.file = own;
        out.push(p);
    }
    std::fs::create_dir_all(folder).map_err(|e| anyhow!("{}: {e}", folder.display()))?;
    for (k, p) in out.iter_mut().enumerate() {
        let from = dir.join(&p.file);
        let ext =
            (from.extension()).map_or("jpg".into(), |e| e.to_string_lossy().to_ascii_lowercase());
        let bytes = std::fs::read(&from).map_err(|e| anyhow!("{}: {e}", from.display()))?;
        let name = image_name(folder, first + k, &ext);
        myriad_measure::files::write_atomic(&folder.join(&name), false, |w| w.write_all(&bytes))?;
        p.file = name;
    }
    Ok(out)
}
