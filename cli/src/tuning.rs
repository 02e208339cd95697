//! `crease tuning`: the tuning keys `crease run --set` and a job spec's `[tuning]` table take, from the
//! registry that checks them ([`crease_jobs::tuning`]).

use anyhow::{bail, Result};
use clap::Args;
use crease_jobs::tuning::markdown;

#[derive(Args, Debug)]
pub struct TuningArgs {
    /// Only the keys whose names start with this (`deform`, `stretch.`, `video.canny`).
    pub prefix: Option<String>,
    /// Print the list as the Markdown page docs/tuning.md holds.
    #[arg(long, conflicts_with = "prefix")]
    pub markdown: bool,
}

pub fn tuning(a: TuningArgs) -> Result<()> {
    if a.markdown {
        print!("{}", markdown::page());
        return Ok(());
    }
    let prefix = a.prefix.unwrap_or_default();
    let list = markdown::listing(&prefix);
    if list.is_empty() {
        bail!(
            "no tuning key starts with `{prefix}` (the groups: deform, partition, stretch, video)"
        );
    }
    print!("{list}");
    Ok(())
}
