//! `isotopo convert`.

use crate::args::*;
use crate::progress;
use clap::Args;
use isotopo::volume::{self};
use isotopo::Result;
use std::path::PathBuf;

#[derive(Args)]
pub(crate) struct ConvertArgs {
    #[command(flatten)]
    input: Input,
    /// Output file; its extension picks the format.
    #[arg(long, short)]
    output: PathBuf,
    #[arg(long, short)]
    quiet: bool,
}

pub(crate) fn run(a: ConvertArgs) -> Result<()> {
    let mut reader = a.input.open()?;
    let bars = progress::Bars::new(a.quiet);
    volume::convert(reader.as_mut(), &a.output, &bars)
}
