//! Regenerates the committed `fixtures/` folder.
//! `cargo run --release -p voltrack-tools --bin make_fixtures [DIR]` (default: fixtures).

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "fixtures".into());
    for (path, bytes) in voltrack::fixtures::files()? {
        let out = std::path::Path::new(&dir).join(&path);
        std::fs::create_dir_all(out.parent().unwrap())?;
        std::fs::write(&out, bytes)?;
        println!("{}", out.display());
    }
    Ok(())
}
