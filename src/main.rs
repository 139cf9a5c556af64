//! The `voltrack` command: parse flags, call the library, print one error with
//! its causes, map to an exit code. All logic lives in the library.

mod cli;

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    match cli::run() {
        Ok(()) => {}
        Err(err) => {
            eprintln!("voltrack: error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            std::process::exit(match err.downcast_ref::<voltrack::Error>() {
                Some(voltrack::Error::InvalidParameter(_)) => 2,
                Some(voltrack::Error::Interrupted) => 130,
                _ => 1,
            });
        }
    }
}
