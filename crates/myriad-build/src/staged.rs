//! A build with inputs or its output on S3-compatible storage (`s3://BUCKET/KEY`, `convert`):
//! the inputs are copied to a folder of this process (under the system's temporary folder,
//! removed however the command ends) and read from there; the dataset is built there and written to the bucket
//! by a multipart upload, so that it appears whole or not at all. Datasets that commands only
//! read are read in place by range requests ([`myriad_format::remote`]).

use myriad_core::{Error, Result};
use myriad_format::s3::{self, Client, Location};
use std::path::{Path, PathBuf};

/// Inputs and output as the build sees them: local files, with what to upload when done.
pub struct Staged {
    _folder: Option<myriad_io::claim::Folder>,
    client: Option<Client>,
    pub inputs: Vec<PathBuf>,
    pub output: PathBuf,
    /// The local copies of `s3://` inputs, with the URL each came from.
    pub copied: std::collections::HashMap<PathBuf, String>,
    upload: Option<Location>,
}

fn location(p: &Path) -> Result<Location> {
    let t = p.to_str().unwrap_or_default();
    s3::parse(t).ok_or_else(|| Error::Invalid(format!("{t}: not s3://BUCKET/KEY")))
}

/// Copies the `s3://` inputs to a folder of this process and, where `output` is on S3, builds
/// there; refuses an S3 output that exists unless `force`. Everything local: nothing copied.
pub fn stage(inputs: &[PathBuf], output: &Path, force: bool) -> Result<Staged> {
    let remote_in = inputs.iter().any(|p| s3::is_s3(p));
    let remote_out = s3::is_s3(output);
    if !remote_in && !remote_out {
        return Ok(Staged {
            _folder: None,
            client: None,
            inputs: inputs.to_vec(),
            output: output.to_path_buf(),
            copied: Default::default(),
            upload: None,
        });
    }
    let client = Client::from_env()?;
    let upload = if remote_out {
        let at = location(output)?;
        if !force && client.exists(&at)? {
            return Err(Error::Invalid(format!(
                "{}: output exists (use --force to replace it)",
                output.display()
            )));
        }
        Some(at)
    } else {
        None
    };
    let folder = myriad_io::claim::Folder::create(&std::env::temp_dir(), ".myriad-s3-")?;
    let (mut local, mut copied) = (Vec::new(), std::collections::HashMap::new());
    for (i, p) in inputs.iter().enumerate() {
        if !s3::is_s3(p) {
            local.push(p.clone());
            continue;
        }
        let at = location(p)?;
        let name = at.key.rsplit('/').next().unwrap_or("input");
        let to = folder.path().join(format!("{i}-{name}"));
        client.download(&at, &to)?;
        copied.insert(to.clone(), p.to_string_lossy().into_owned());
        local.push(to);
    }
    let output = match &upload {
        Some(at) => folder
            .path()
            .join(at.key.rsplit('/').next().unwrap_or("out.myr")),
        None => output.to_path_buf(),
    };
    Ok(Staged {
        _folder: Some(folder),
        client: Some(client),
        inputs: local,
        output,
        copied,
        upload,
    })
}

impl Staged {
    /// Uploads the dataset built where its output is on S3.
    pub fn finish(&self) -> Result<()> {
        if let (Some(at), Some(c)) = (&self.upload, &self.client) {
            c.upload(&self.output, at)?;
        }
        Ok(())
    }
}
