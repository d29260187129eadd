//! The `driftless` binary: everything lives in the library's `cli` module.

fn main() -> std::process::ExitCode {
    driftless::cli::main()
}
