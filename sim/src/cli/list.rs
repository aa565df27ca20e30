//! `mgmot-sim list`: the shipped scenarios.

use mgmot_sim::scenario::{Scenario, SHIPPED};

/// Arguments of `list`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print the TOML of this shipped scenario instead of the list (a starting point for
    /// your own file).
    #[arg(long)]
    show: Option<String>,
}

/// Prints name, duration and description of every shipped scenario.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(name) = args.show {
        let Some((_, text)) = SHIPPED.iter().find(|(n, _)| *n == name) else {
            anyhow::bail!("no shipped scenario `{name}` (see `mgmot-sim list`)");
        };
        print!("{text}");
        return Ok(());
    }
    for (name, text) in SHIPPED {
        let s = Scenario::from_toml(text, name)?;
        println!("{name:<20} {:>6.0} s  {}", s.duration_s, s.description);
    }
    Ok(())
}
