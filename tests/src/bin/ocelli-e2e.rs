fn main() -> std::process::ExitCode {
    deploy::cli::main()
}
