//! `myriad serve INPUT... [--bind ADDR] [--open]`: datasets, scans and folders of exported
//! files over HTTP (myriad-serve), until the process is stopped.

use anyhow::{Context, Result};
use clap::Args;
use myriad_serve::{Catalog, Kind, Options, Server, href};
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;

#[derive(Args)]
pub struct ServeArgs {
    /// Datasets (.myr), COPC or LAS/LAZ files, folders of exported files (Potree)
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Address and port to listen on (another machine can connect only when this is not a
    /// loopback address); port 0 takes any free port
    #[arg(long, default_value = "127.0.0.1:8080")]
    bind: SocketAddr,
    /// Open the index page in a browser
    #[arg(long)]
    open: bool,
    /// Connections served at once (when full, the one idle the longest is closed for a new one)
    #[arg(long, default_value_t = 512)]
    max_connections: usize,
    /// Seconds a client has from connecting to send its first request
    #[arg(long, default_value_t = 10.0)]
    header_timeout: f64,
    /// Seconds after which a connection on which nothing moves is closed
    #[arg(long, default_value_t = 30.0)]
    idle_timeout: f64,
    /// Most points a box download (/x/) may hold; a larger box is answered 413
    #[arg(long, default_value_t = 20_000_000)]
    max_box_points: u64,
    /// Print a line on stderr for each request: method, path, range, status, bytes
    #[arg(long)]
    log: bool,
    /// Let viewers save their annotations and measurements (PUT /work/NAME writes the
    /// dataset's NAME.work.json); without it the work is shown, not changed
    #[arg(long)]
    edit: bool,
}

pub fn run(a: ServeArgs) -> Result<()> {
    // Datasets, COPC files and folders as they are; any other scan as a dataset made from it
    // (kept for next time), named after it.
    let mut catalog = Catalog::default();
    for input in &a.inputs {
        let name = input
            .file_name()
            .map(|n| n.to_string_lossy().to_lowercase());
        let raw = input.is_dir()
            || myriad_format::is_dataset(input)
            || name.is_some_and(|n| n.ends_with(".copc.laz"));
        if raw {
            catalog.add_input(input)?;
        } else {
            let ds = crate::cached::dataset_for(input)?;
            let stem = input.file_stem().unwrap_or_default().to_string_lossy();
            catalog.add_file_as(&format!("{stem}.myr"), &ds, input)?;
        }
    }
    let names: Vec<(String, Kind, u64)> = catalog
        .names()
        .map(|(n, kind, len)| (n.to_string(), kind, len))
        .collect();
    let seconds = |s: f64, flag: &str| -> Result<std::time::Duration> {
        if !(s.is_finite() && s > 0.0 && s <= 86_400.0) {
            anyhow::bail!("{flag} must be a number of seconds from 0 to 86400");
        }
        Ok(std::time::Duration::from_secs_f64(s))
    };
    let server = Server::start(
        catalog,
        a.bind,
        Options {
            max_connections: a.max_connections,
            header_timeout: seconds(a.header_timeout, "--header-timeout")?,
            idle_timeout: seconds(a.idle_timeout, "--idle-timeout")?,
            max_box_points: a.max_box_points,
            stop_on_signals: true,
            log: a.log,
            edit: a.edit,
            ..Options::default()
        },
    )
    .with_context(|| format!("cannot listen on {}", a.bind))?;
    let base = format!("http://{}", server.addr);
    let mut out = std::io::stdout().lock();
    writeln!(out, "serving {} files on {base}/", names.len())?;
    for (n, kind, len) in &names {
        writeln!(
            out,
            "  {base}/d/{} ({} bytes)",
            href(n),
            myriad_core::units::thousands(*len)
        )?;
        if *kind == Kind::Dataset {
            writeln!(out, "    in the browser: {base}/view/{}", href(n))?;
        }
    }
    writeln!(out, "stop with Ctrl-C")?;
    out.flush()?;
    drop(out);
    if a.open {
        // The desktop's browser, where there is one, on the first dataset (else the index);
        // the server runs on either way.
        let page = match names.iter().find(|(_, kind, _)| *kind == Kind::Dataset) {
            Some((n, _, _)) => format!("{base}/view/{}", href(n)),
            None => format!("{base}/"),
        };
        if let Err(e) = std::process::Command::new("xdg-open").arg(&page).spawn() {
            eprintln!("warning: could not open a browser ({e}); open {page}");
        }
    }
    // Until Ctrl-C or SIGTERM; the server's temporary files go with it.
    server.wait();
    Ok(())
}
