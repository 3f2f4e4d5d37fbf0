//! Print the thesis-like sample pocket (Bayesteh 2013 ch. 3) that feedopt's
//! tests, benchmark and docs use: `cargo run --example feedopt_pocket -- iso|pmac`.

use microcam::feedopt::sample::Pocket;
use microcam::gcode::Dialect;

fn main() {
    let d = match std::env::args().nth(1).as_deref() {
        Some("pmac") => Dialect::Pmac,
        _ => Dialect::Iso,
    };
    print!("{}", Pocket::default().program(d));
}
