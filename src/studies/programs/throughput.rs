//! Single-thread force-loop throughput of each elastic operator on case 2 (dp = 0.025, 300
//! steps): directed bonds evaluated per second per force pass, the figure of BENCHMARKS.md.
//! `cargo run --release -- study throughput [corrected|second_order|paper] [repeats]`.
use crate::physics::ElasticModel;
use crate::studies::bench::single_thread_throughput;

pub fn main(args: Vec<String>) {
    let args: Vec<String> = args.clone().into_iter().skip(1).collect();
    let models: Vec<(&str, ElasticModel)> = [
        ("corrected", ElasticModel::Corrected),
        ("second_order", ElasticModel::SecondOrder),
        ("paper", ElasticModel::Paper),
    ]
    .into_iter()
    .filter(|(n, _)| args.is_empty() || args.iter().any(|a| a == n))
    .collect();
    let repeats = args
        .iter()
        .find_map(|a| a.parse::<usize>().ok())
        .unwrap_or(3);
    for (name, model) in models {
        // The best of a few runs: the machine is shared, the lowest figure is the noise.
        let best = (0..repeats)
            .filter_map(|_| single_thread_throughput(model).ok())
            .fold(0.0f64, f64::max);
        println!("{name}: {best:.3e} pair-updates/s per core");
    }
}
