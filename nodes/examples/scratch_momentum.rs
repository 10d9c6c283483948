use std::sync::Arc;
use kinegraph_nodes::builtin::momentum::analysis::{analyse, AnalysisOptions};
use kinegraph_nodes::formats::bvh::{read_bvh_file, BvhReadOptions};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (clip, _) = read_bvh_file(std::path::Path::new(&args[1]), BvhReadOptions::default()).unwrap().value;
    let clip = Arc::new(clip.slice(1, clip.frame_count()));
    let a = analyse(clip.clone(), &AnalysisOptions::default(), None, None).unwrap();
    let step: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(10);
    println!("fps {} frames {} phases {:?}", clip.fps(), clip.frame_count(), a.phases);
    println!("double support {:?}", a.contacts.double_support.iter().map(|r| (r.start, r.end)).collect::<Vec<_>>());
    for f in (0..clip.frame_count()).step_by(step) {
        let l = a.smoothed[f];
        println!("{f:5} {:6.2}s |L| {:7.2}  L=({:6.1},{:6.1},{:6.1}) ds={}", f as f64 / clip.fps(), l.length(), l.x, l.y, l.z, a.in_double_support(f) as u8);
    }
}
