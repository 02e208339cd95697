//! `crease deep`, `crease bake` and `crease bench --deep` in a build without the learning stack (the `deep`
//! feature, off by default so that the first build compiles no candle): each says in one line how to get it.

use anyhow::{bail, Result};
use clap::Args;

/// The line every DeepWrinkles command prints in this build.
pub const HOW_TO_GET_IT: &str = "DeepWrinkles is not in this build of crease (it leaves out the learning stack); \
build it with `cargo build --release --features deep` or install it with `cargo install --path cli --features deep`";

/// Whatever follows `crease deep` or `crease bake`, taken as it is: this build cannot run it.
#[derive(Args, Debug)]
pub struct Unavailable {
    /// The command's arguments, which this build cannot run (see above for how to get a build that can).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    _args: Vec<String>,
}

pub type DeepArgs = Unavailable;
pub type BakeArgs = Unavailable;

pub fn deep(_: DeepArgs) -> Result<()> {
    bail!(HOW_TO_GET_IT)
}

pub fn bake(_: BakeArgs) -> Result<()> {
    bail!(HOW_TO_GET_IT)
}

#[cfg(test)]
mod tests {
    use crate::Cli;
    use clap::Parser;

    /// Whatever a DeepWrinkles command line holds, this build answers it with the one line saying how to get it.
    #[test]
    fn deep_commands_say_how_to_get_deepwrinkles() {
        for line in [
            &["crease", "deep", "train", "--data", "d", "--out", "m"][..],
            &[
                "crease", "deep", "apply", "--model", "m", "--pose", "p.json",
            ],
            &["crease", "bake", "--fine", "f", "--coarse", "c"],
        ] {
            let cli = Cli::try_parse_from(line).expect("parsed");
            let err = crate::run_command(cli.command).unwrap_err().to_string();
            assert_eq!(err, super::HOW_TO_GET_IT, "{line:?}");
        }
        let err = crate::run_command(
            Cli::try_parse_from(["crease", "bench", "--deep"])
                .unwrap()
                .command,
        )
        .unwrap_err()
        .to_string();
        assert_eq!(err, super::HOW_TO_GET_IT);
    }
}
