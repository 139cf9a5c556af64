//! The `voltrack` command: parse flags, call the library, print one error with
//! its causes, map to an exit code. All logic lives in the library.

mod cli;

fn main() {
    cli::init_logging();
    match cli::run() {
        Ok(()) => {}
        Err(err) => {
            let message = err.to_string();
            eprintln!("voltrack: error: {message}");
            // Our errors often quote their cause already ("file: reason").
            for cause in err
                .chain()
                .skip(1)
                .map(|c| c.to_string())
                .filter(|c| !message.contains(c.as_str()))
            {
                eprintln!("  caused by: {cause}");
            }
            if let Some(voltrack::Error::Interrupted { saved: Some(_) }) =
                err.downcast_ref::<voltrack::Error>()
            {
                eprintln!("  run the same command with --resume to continue");
            }
            std::process::exit(match err.downcast_ref::<voltrack::Error>() {
                Some(
                    voltrack::Error::InvalidParameter(_) | voltrack::Error::OutputRefused { .. },
                ) => 2,
                Some(voltrack::Error::Interrupted { .. }) => 130,
                _ => 1,
            });
        }
    }
}
