//! The `streak` command: parse, run, report.

mod cli;

fn main() {
    if let Err(error) = cli::run() {
        eprintln!("streak: {error}");
        std::process::exit(1);
    }
}
