use anyhow::Result; #[derive(clap::Args, Debug)] pub struct BenchArgs {} pub fn bench(_a: BenchArgs) -> Result<()> { Ok(()) }
