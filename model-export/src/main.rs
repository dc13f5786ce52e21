use clap::Parser;

fn main() -> std::process::ExitCode {
    match model_export::cli::run(model_export::cli::Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
