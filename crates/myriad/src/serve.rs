//! `myriad serve INPUT... [--bind ADDR] [--open]`: datasets, scans and folders of exported
//! files over HTTP (myriad-serve), until the process is stopped.

use anyhow::{Context, Result};
use clap::Args;
use myriad_build::open::{Opened, Opener, Pending, Preview};
use myriad_serve::{Catalog, Kind, Options, Server, href};
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Args)]
pub struct ServeArgs {
    /// Datasets (.myr), COPC or LAS/LAZ files, folders of exported files (Potree); a dataset
    /// or COPC file on S3 (s3://BUCKET/KEY) or a web server, read from there as it is asked for
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
    #[arg(help_heading = "Limits", long, default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    max_connections: u32,
    /// Seconds a client has from connecting to send its first request
    #[arg(help_heading = "Limits", long, default_value_t = 10.0)]
    header_timeout: f64,
    /// Seconds after which a connection on which nothing moves is closed
    #[arg(help_heading = "Limits", long, default_value_t = 30.0)]
    idle_timeout: f64,
    /// Most points a box download (/x/) may hold; a larger box is answered 413
    #[arg(help_heading = "Limits", long, default_value_t = 20_000_000)]
    max_box_points: u64,
    /// Print a line on stderr for each request: method, path, range, status, bytes
    #[arg(long)]
    log: bool,
    /// Let viewers save their annotations and measurements (PUT /work/NAME writes the
    /// dataset's NAME.work.json); without it the work is shown, not changed
    #[arg(long)]
    edit: bool,
    /// Let pages of this origin read what is served (CORS), as https://host:port, or * for any
    /// page (a viewer or a static site on another host); may be given again. Without it pages
    /// of other origins read nothing; none ever writes
    #[arg(long, value_name = "ORIGIN", value_parser = parse_origin)]
    allow_origin: Vec<String>,
    /// A name this server answers to when bound to a loopback address (a reverse proxy's public
    /// name, which it passes on in Host); requests naming another host are refused, so that a
    /// page whose name was rebound to 127.0.0.1 cannot read or write; may be given again
    #[arg(long, value_name = "NAME")]
    server_name: Vec<String>,
    /// Serve privately: only requests with one of this file's tokens (one a line, 16
    /// characters or more) as "Authorization: Bearer TOKEN", the cookie of the one-time link
    /// printed at start, or a signed link (--sign)
    #[arg(help_heading = "Privacy", long, value_name = "FILE")]
    token_file: Option<PathBuf>,
    /// Print a link to URL (http://HOST:PORT/view/NAME or /d/NAME) signed with --token-file's
    /// key, good until --expires, and exit
    #[arg(
        help_heading = "Privacy",
        long,
        value_name = "URL",
        requires = "token_file"
    )]
    sign: Option<String>,
    /// How long a signed link holds: 90s, 30m, 24h, 7d
    #[arg(
        help_heading = "Privacy",
        long,
        default_value = "24h",
        requires = "sign"
    )]
    expires: String,
    /// Serve HTTPS with this certificate chain (PEM; with --tls-key)
    #[arg(
        help_heading = "Privacy",
        long,
        value_name = "CERT.pem",
        requires = "tls_key"
    )]
    tls_cert: Option<PathBuf>,
    /// The private key of --tls-cert (PEM)
    #[arg(
        help_heading = "Privacy",
        long,
        value_name = "KEY.pem",
        requires = "tls_cert"
    )]
    tls_key: Option<PathBuf>,
}

/// The token file's access rules; `None` without one.
fn access(a: &ServeArgs) -> Result<Option<myriad_serve::access::Access>> {
    let Some(f) = &a.token_file else {
        return Ok(None);
    };
    // Tokens are lines of 16 characters or more: a megabyte holds thousands.
    let bytes = myriad_io::read_small(f, 1 << 20)
        .with_context(|| format!("{}: cannot read the token file", f.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{}: the token file is not UTF-8 text", f.display()))?;
    let access = myriad_serve::access::Access::from_tokens(&text)
        .map_err(|e| anyhow::anyhow!("{}: {e}", f.display()))?;
    Ok(Some(access))
}

/// `--sign URL`: the URL with its signature for the dataset it names.
fn signed(access: &myriad_serve::access::Access, url: &str, expires: &str) -> Result<String> {
    let seconds = myriad_serve::access::parse_duration(expires).map_err(anyhow::Error::msg)?;
    let (base, query) = url.split_once('?').unwrap_or((url, ""));
    let path = base
        .split_once("://")
        .and_then(|(_, rest)| rest.find('/').map(|i| &rest[i..]))
        .unwrap_or("");
    let name = myriad_serve::access::dataset_of(path).ok_or_else(|| {
        anyhow::anyhow!(
            "--sign {url}: a dataset's address is expected (http://HOST:PORT/view/NAME or /d/NAME)"
        )
    })?;
    let until = myriad_serve::access::now() + seconds;
    let sig = access.sign(&name, until);
    Ok(if query.is_empty() {
        format!("{base}?{sig}")
    } else {
        format!("{base}?{query}&{sig}")
    })
}

/// The catalog of what `inputs` serve, and the scans served before their datasets, to build.
/// Datasets, COPC files and folders of exported files as they are (a dataset or COPC file on S3
/// or a web server read from there); any other scan as a dataset made from it (kept for next
/// time), named after it (a folder of tiles after the folder: `tiles/` -> tiles.myr). A LAS/LAZ
/// scan (or folder of tiles) without its dataset is served at once: its preview, then its build
/// as it goes, then its dataset.
fn catalog_of(inputs: &[PathBuf], opener: &mut Opener) -> Result<(Catalog, Vec<Served>)> {
    let mut catalog = Catalog::default();
    let mut scans = Vec::new();
    for input in inputs {
        if myriad_build::open::served_as_is(input) {
            catalog.add_input(input)?;
            continue;
        }
        let stem = if input.is_dir() {
            input.file_name()
        } else {
            input.file_stem()
        };
        let name = format!("{}.myr", stem.unwrap_or_default().to_string_lossy());
        match crate::cached::open(opener, input)? {
            Opened::Dataset(ds) => {
                let live = myriad_serve::live::Live::built(&ds);
                catalog.add_live(&name, live.clone(), &ds, input)?;
                scans.push(Served {
                    scan: input.clone(),
                    live,
                    pending: None,
                });
            }
            Opened::Preview(pending) => {
                let preview = (pending.preview.as_ref()).context("a preview without a dataset")?;
                let live = myriad_serve::live::Live::new(preview);
                catalog.add_live(&name, live.clone(), preview, input)?;
                eprintln!(
                    "{}: serving its preview while its dataset is built",
                    input.display()
                );
                scans.push(Served {
                    scan: input.clone(),
                    live,
                    pending: Some(pending),
                });
            }
        }
    }
    Ok((catalog, scans))
}

/// A scan served under a name, what serves it, and its build while one is to run.
struct Served {
    scan: PathBuf,
    live: Arc<myriad_serve::live::Live>,
    pending: Option<Pending>,
}

/// Builds the scans served before their datasets, one after another as they come, each served
/// as it goes.
fn build_served(to_build: std::sync::mpsc::Receiver<(Pending, Arc<myriad_serve::live::Live>)>) {
    for (pending, live) in to_build {
        let g = myriad_build::growing::Growing::new(myriad_build::growing::DEFAULT_EVERY);
        live.building(g.clone());
        match crate::cached::build(&pending, Some(g)) {
            Ok(d) => {
                live.ended(Some(d));
                eprintln!(
                    "{}: its dataset is built, served from now on",
                    pending.scan.display()
                );
            }
            Err(e) => {
                live.failed(&format!("{e:#}"));
                eprintln!(
                    "error: {e:#} ({}: answered as failed from now on)",
                    pending.scan.display()
                );
            }
        }
    }
}

/// How often served scans are looked at for a change since their dataset was built.
const WATCH_EVERY: std::time::Duration = std::time::Duration::from_secs(3);

/// Looks at the served scans every [`WATCH_EVERY`]: one whose built dataset is no longer its
/// own (its files' sizes, times or content changed: `myriad_build::cached`) is served from its
/// new preview, of a new generation ([`myriad_serve::live::Live::restart`]), and built again.
fn watch_served(
    scans: Vec<(PathBuf, Arc<myriad_serve::live::Live>)>,
    opener: Arc<std::sync::Mutex<Option<Opener>>>,
    to_build: std::sync::mpsc::Sender<(Pending, Arc<myriad_serve::live::Live>)>,
) {
    loop {
        std::thread::sleep(WATCH_EVERY);
        for (scan, live) in &scans {
            let Some(built) = live.dataset() else {
                continue;
            };
            if myriad_build::cached::existing(scan).as_ref() == Some(&built) || !scan.exists() {
                continue;
            }
            let opened = {
                let mut o = opener.lock().expect("opener lock");
                // The server is stopping: its previews' folder is gone.
                let Some(o) = o.as_mut() else { return };
                crate::cached::open(o, scan)
            };
            match opened {
                Ok(Opened::Preview(pending)) => {
                    let Some(preview) = pending.preview.clone() else {
                        continue;
                    };
                    eprintln!(
                        "{}: changed since its dataset was built: serving its preview while it is built again",
                        scan.display()
                    );
                    live.restart(&preview);
                    if to_build.send((pending, live.clone())).is_err() {
                        return;
                    }
                }
                Ok(Opened::Dataset(d)) => {
                    live.restart(&d);
                    live.ended(Some(d));
                }
                Err(e) => eprintln!("warning: {e:#} (still serving what was built)"),
            }
        }
    }
}

/// A number of seconds given as `flag`, checked.
fn seconds(s: f64, flag: &str) -> Result<std::time::Duration> {
    if !(s.is_finite() && s > 0.0 && s <= 86_400.0) {
        anyhow::bail!("{flag} must be a number of seconds from 0 to 86400");
    }
    Ok(std::time::Duration::from_secs_f64(s))
}

/// What the server's first lines say: each file's address, the viewer's for datasets, and how a
/// browser signs in to a private server.
fn print_addresses(server: &Server, names: &[(String, Kind, u64)], base: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "serving {} files on {base}/", names.len())?;
    for (n, kind, len) in names {
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
    if let Some(login) = server.one_time_link() {
        writeln!(
            out,
            "private: requests need a token from the token file; a browser signs in once with {base}{login}"
        )?;
    }
    writeln!(out, "stop with Ctrl-C")?;
    out.flush()?;
    Ok(())
}

/// The desktop's browser, where there is one, on the first dataset (else the index); the
/// server runs on either way.
fn open_browser(names: &[(String, Kind, u64)], base: &str) {
    let page = match names.iter().find(|(_, kind, _)| *kind == Kind::Dataset) {
        Some((n, _, _)) => format!("{base}/view/{}", href(n)),
        None => format!("{base}/"),
    };
    if let Err(e) = std::process::Command::new("xdg-open").arg(&page).spawn() {
        eprintln!("warning: could not open a browser ({e}); open {page}");
    }
}

pub fn run(a: ServeArgs) -> Result<()> {
    let access = access(&a)?;
    if let (Some(url), Some(access)) = (&a.sign, &access) {
        println!("{}", signed(access, url, &a.expires)?);
        return Ok(());
    }
    let private = access.is_some();
    let tls = match (&a.tls_cert, &a.tls_key) {
        (Some(c), Some(k)) => Some(myriad_serve::tls::acceptor(c, k).map_err(anyhow::Error::msg)?),
        _ => None,
    };
    let scheme = if tls.is_some() { "https" } else { "http" };
    if private && tls.is_none() && !a.bind.ip().is_loopback() {
        eprintln!(
            "warning: --token-file without --tls-cert on {}: tokens and cookies cross the network in clear",
            a.bind
        );
    }
    let mut opener = Opener::new(Preview::Dataset);
    let (catalog, scans) = catalog_of(&a.inputs, &mut opener)?;
    let names: Vec<(String, Kind, u64)> = catalog
        .names()
        .map(|(n, kind, len)| (n.to_string(), kind, len))
        .collect();
    let server = Server::start_with(
        catalog,
        a.bind,
        Options {
            max_connections: a.max_connections as usize,
            header_timeout: seconds(a.header_timeout, "--header-timeout")?,
            idle_timeout: seconds(a.idle_timeout, "--idle-timeout")?,
            max_box_points: a.max_box_points,
            stop_on_signals: true,
            log: a.log,
            edit: a.edit,
            allow_origins: a.allow_origin.clone(),
            server_names: a.server_name.clone(),
            ..Options::default()
        },
        access,
        tls,
    )
    .with_context(|| format!("cannot listen on {}", a.bind))?;
    let base = format!("{scheme}://{}", server.addr);
    print_addresses(&server, &names, &base)?;
    let (send, receive) = std::sync::mpsc::channel();
    let mut watched = Vec::new();
    for s in scans {
        if let Some(p) = s.pending {
            send.send((p, s.live.clone()))?;
        }
        watched.push((s.scan, s.live));
    }
    std::thread::spawn(move || build_served(receive));
    let opener = Arc::new(std::sync::Mutex::new(Some(opener)));
    if !watched.is_empty() {
        let o = opener.clone();
        std::thread::spawn(move || watch_served(watched, o, send));
    }
    if a.open {
        open_browser(&names, &base);
    }
    // Until Ctrl-C or SIGTERM; the server's temporary files (and the previews') go with it.
    server.wait();
    drop(opener.lock().expect("opener lock").take());
    Ok(())
}

/// An origin as browsers send it (`scheme://host[:port]`, no path), or `*`.
fn parse_origin(s: &str) -> std::result::Result<String, String> {
    let ok = s == "*"
        || s.split_once("://").is_some_and(|(scheme, rest)| {
            matches!(scheme, "http" | "https")
                && !rest.is_empty()
                && !rest.contains(['/', '?', '#'])
        });
    match ok {
        true => Ok(s.trim_end_matches('/').to_string()),
        false => Err(format!(
            "{s:?}: an origin is scheme://host[:port] (https://example.org:8443), or *"
        )),
    }
}
