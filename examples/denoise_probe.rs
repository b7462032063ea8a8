//! Tuning probe for the `normal-filter` smoothing method (issue #26): the noise protocol of
//! the smoothing thesis (docs/smoothing.md) on the four scans, Taubin (13 λ|μ pairs, the `smooth` step) against
//! normal-filter settings, all measured with `compare` against the clean scan.
//!
//! `cargo run --release --example denoise_probe -- [SIGMA] 'toml params' …`
//! Each argument after SIGMA (default 0.2) is a normal-filter setting written as the
//! recipe's step parameters without `method`, e.g. `"sigma_r = 0.3\nnormal_passes = 8"`
//! (an empty string for the defaults). `FP_SCANS=bunny,igea` limits the scans.
//! Prints per scan and setting: result → clean mean distance (% of the diagonal), its
//! ratio to Taubin's, the volume change, the face-normal angle and the step's time.

#[path = "common/noise_protocol.rs"]
#[allow(dead_code)]
mod noise_protocol;

use noise_protocol::{SCANS, load, wanted};
use scanmill::compare::{CompareOptions, NamedRecipe, run_on_mesh};
use scanmill::metrics::MetricsOptions;
use scanmill::metrics::noise::NoiseOptions;
use scanmill::recipe::Recipe;
use std::path::Path;

fn recipe(name: &str, step: &str) -> NamedRecipe {
    let text = format!("[[step]]\nkind = \"smooth\"\n{step}\n");
    NamedRecipe {
        name: name.to_string(),
        recipe: Recipe::from_toml(&text, Path::new(name)).unwrap_or_else(|e| panic!("{name}: {e}")),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let sigma: f64 = args.next().map_or(0.2, |s| s.parse().expect("SIGMA"));
    let settings: Vec<String> = args.collect();
    let mut recipes = vec![recipe("taubin ×13", "method = \"taubin\"")];
    for s in &settings {
        let label = s.replace('\n', "; ");
        let label = if label.is_empty() {
            "defaults".into()
        } else {
            label
        };
        recipes.push(recipe(&label, &format!("method = \"normal-filter\"\n{s}")));
    }
    let options = CompareOptions {
        noise: Some(NoiseOptions {
            sigma_factor: sigma,
            ..NoiseOptions::default()
        }),
        metrics: MetricsOptions {
            samples: 100_000,
            ..Default::default()
        },
    };
    for (name, rel) in SCANS {
        if !wanted(name) {
            continue;
        }
        let clean = load(rel);
        let t = run_on_mesh(&clean, name, &recipes, &options).unwrap();
        let taubin = t.rows[1].to_clean_mean_percent.unwrap();
        println!(
            "{name} σ = {sigma}: noisy {:.4} %",
            t.rows[0].to_clean_mean_percent.unwrap()
        );
        for row in &t.rows[1..] {
            if let Some(e) = &row.error {
                println!("  {:<50} error {e}", row.name);
                continue;
            }
            let d = row.to_clean_mean_percent.unwrap();
            println!(
                "  {:<50} {d:.4} % ({:.3}×)  vol {:>+7.3} %  angle {:.4}  {:>6.0} ms",
                row.name,
                d / taubin,
                row.volume_change_percent.unwrap_or(f64::NAN),
                row.angular_mean.unwrap_or(f64::NAN),
                row.time_ms
            );
        }
    }
}
