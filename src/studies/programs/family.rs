//! Issue 24's family of bodies written as a user would (module `studies::family`): linearised
//! first frequency and static deflection against the FEM, per clamp style and shape, with the
//! scene's accuracy warnings. `mps study family 4 8` (THREE_D=1 adds the 3D cantilevers;
//! ONLY=text keeps the cases whose name contains it; PEAK=1 adds the first peak under sudden
//! gravity in the time domain; SHAPE_EXTRA=0.2,0.5 sets how much thicker than n spacings the
//! rows of the box written as a shape are).
use crate::studies::family::family_markdown;

pub fn main(args: Vec<String>) {
    let ns: Vec<usize> = args.iter().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ns = if ns.is_empty() { vec![4] } else { ns };
    let three_d = std::env::var("THREE_D").is_ok();
    let only = std::env::var("ONLY").ok();
    let peaks = std::env::var("PEAK").is_ok();
    print!("{}", family_markdown(&ns, three_d, peaks, only.as_deref()));
}
