//! Rewrites a LAS/LAZ file as LAS or LAZ (by the output's extension), keeping its point format,
//! VLRs and point order: `cargo run --release -p myriad-io --example translate IN OUT`. Used to
//! make the LAS copy of a LAZ file for the LAS-input benchmark.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: translate IN.las|laz OUT.las|laz");
        std::process::exit(2);
    }
    let (input, output) = (
        std::path::Path::new(&args[1]),
        std::path::Path::new(&args[2]),
    );
    let mut src = myriad_io::las::LasSource::open(input)?;
    let options = myriad_io::las::LasWriteOptions::like(src.header());
    let mut sink = myriad_io::las::LasSink::create(output, options, true)?;
    use myriad_io::PointSource;
    while let Some(b) = src.read_batch(myriad_io::MAX_BATCH)? {
        sink.write(&b)?;
    }
    println!("{} points", sink.finish()?);
    Ok(())
}
