//! What the command-line tests share: running the built `isotopo`.

use std::process::Command;

/// Runs `isotopo` with `args`: (exit code, stdout, stderr).
pub fn isotopo(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_isotopo"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}
