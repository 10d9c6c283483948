//! The angular-momentum concatenation on real CMU clips: its properties, its refusals and
//! the body model's plausibility. Needs `../shared/data` (skips without it outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::sync::Arc;

use kinegraph_nodes::builtin::clip_edit::trim;
use kinegraph_nodes::builtin::momentum::concat::{ConcatParams, Support, concatenate};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::align::Rule;
use kinegraph_nodes::kernels::analysis::{AnalysisOptions, analyse};
use kinegraph_nodes::kernels::baseline::{BaselineParams, concatenate_baseline};
use kinegraph_nodes::kernels::join::{ConcatError, Concatenated};
use kinegraph_nodes::model::Clip;

fn clip(data: &Path, name: &str, from_secs: f64, to_secs: f64) -> Arc<Clip> {
    let (clip, _) = read_bvh_file(&data.join("bvh").join(name), BvhReadOptions::default()).unwrap().value;
    Arc::new(trim(&clip, from_secs, Some(to_secs)).unwrap())
}

/// The two front kicks of CMU 144_05 (0.5–2.2 s and 2.2–3.9 s) and their join under `params`.
fn double_kick(data: &Path, params: &ConcatParams) -> (Arc<Clip>, Arc<Clip>, Concatenated) {
    let options = AnalysisOptions::default();
    let first = clip(data, "cmu/144_05.bvh", 0.5, 2.2);
    let second = clip(data, "cmu/144_05.bvh", 2.2, 3.9);
    let (a, b) =
        (analyse(first.clone(), &options, None, None).unwrap(), analyse(second.clone(), &options, None, None).unwrap());
    let joined = concatenate(&a, &b, params, &options).unwrap();
    (first, second, joined)
}

/// The error of a refused concatenation (a success prints its report, not its clip).
fn refusal(result: Result<Concatenated, ConcatError>) -> ConcatError {
    match result {
        Ok(joined) => panic!("expected a refusal, got {:?}", joined.report),
        Err(e) => e,
    }
}

fn number(report: &kinegraph_nodes::node::Report, key: &str) -> f64 {
    report[key].as_f64().unwrap_or_else(|| panic!("{key} missing from {report:?}"))
}

#[test]
fn a_clip_concatenated_with_itself_joins_at_its_momentum_peak() {
    let Some(data) = shared_data() else { return };
    // CMU 90_02 without its leading T-pose frame: one cartwheel.
    let c = clip(&data, "cmu/90_02.bvh", 0.01, 6.5);
    let options = AnalysisOptions::default();
    let a = analyse(c.clone(), &options, None, None).unwrap();
    let params = ConcatParams { support: Support::Any, ..ConcatParams::default() };
    let joined = concatenate(&a, &a, &params, &options).unwrap();
    let r = &joined.report;
    // The halves of the main phase meet at t_m, where the two copies' momenta agree: the
    // join lands within 0.1 s of the peak, with a near-zero offset and cost.
    let near = 0.1 * c.fps();
    eprintln!("self-concatenation of 90_02: {r:?}");
    assert!((number(r, "blend_centre_frame") - a.phases.main_frame as f64).abs() <= near, "{r:?}");
    assert!(number(r, "offset_frames").abs() <= near, "{r:?}");
    assert!(number(r, "relative_cost") < 1e-3, "{r:?}");
    assert!(number(r, "yaw_deg").abs() < 1e-6);
}

#[test]
fn mirrored_cartwheels_are_refused_for_facing_under_the_forward_rule() {
    let Some(data) = shared_data() else { return };
    // 144_01 goes there and back: the second cartwheel turns the other way.
    let options = AnalysisOptions::default();
    let a = analyse(clip(&data, "cmu/144_01.bvh", 1.3, 4.3), &options, None, None).unwrap();
    let b = analyse(clip(&data, "cmu/144_01.bvh", 4.4, 7.2), &options, None, None).unwrap();
    let err = refusal(concatenate(&a, &b, &ConcatParams::default(), &options));
    assert!(matches!(err, ConcatError::Facing { angle_deg, .. } if angle_deg > 45.0), "{err}");
    assert!(err.to_string().contains("do not chain"));
}

#[test]
fn a_one_two_punch_is_shorter_than_the_motion_graphs_join_and_costs_are_reported() {
    let Some(data) = shared_data() else { return };
    let options = AnalysisOptions::default();
    let a = analyse(clip(&data, "cmu/79_08.bvh", 2.2, 3.1), &options, None, None).unwrap();
    let b = analyse(clip(&data, "cmu/79_08.bvh", 3.6, 4.6), &options, None, None).unwrap();
    let params = ConcatParams { rule: Rule::Reverse, ..ConcatParams::default() };
    let joined = concatenate(&a, &b, &params, &options).unwrap();
    let baseline = concatenate_baseline(&a, &b, &BaselineParams::default(), &options).unwrap();
    let r = &joined.report;
    assert!(number(r, "duration_secs") < number(&baseline.report, "duration_secs"));
    // The blend is centred inside both blendable periods (the first clip's frames, and
    // shifted by the offset the second's; ranges end-exclusive, window inclusive), and the
    // window stays inside them unless it had to grow beyond to the shortest blend
    // (`min_blend_secs`, 0.25 s): then it is exactly that long.
    let pair = |key: &str| {
        let v = r[key].as_array().unwrap_or_else(|| panic!("{key} missing from {r:?}"));
        (v[0].as_i64().unwrap(), v[1].as_i64().unwrap())
    };
    let ((f0, ff), t) = (pair("window_frames"), number(r, "offset_frames") as i64);
    let (first, second) = (pair("blendable_first"), pair("blendable_second"));
    let within = |f: i64| first.0 <= f && f < first.1 && second.0 <= f - t && f - t < second.1;
    let centre = number(r, "blend_centre_frame") as i64;
    assert!(within(centre), "centre {centre} outside the blendable periods {first:?}, {second:?} (offset {t})");
    let shortest = (0.25 * a.clip.fps()).round() as i64;
    assert!(
        (within(f0) && within(ff)) || ff - f0 == shortest,
        "window {f0}..={ff} leaves the blendable periods {first:?}, {second:?} (offset {t}) though longer than {shortest} frames"
    );
    // The result is the first clip up to the window, the window played over (ff − f0) / s
    // frame intervals (eq. 9's time scale), then the second clip from the window's end on.
    let s = number(r, "time_scale");
    let window_out = ((ff - f0) as f64 / s).round().max(1.0) as usize;
    let expected = f0 as usize + window_out + (b.clip.frame_count() - (ff - t) as usize);
    assert_eq!(joined.clip.frame_count(), expected, "s = {s}, window {f0}..={ff}, offset {t}");
    // Refused as too different under an impossible cost limit, with the terms in the text.
    let strict = ConcatParams { max_relative_cost: 1e-9, ..params };
    let err = refusal(concatenate(&a, &b, &strict, &options));
    assert!(matches!(err, ConcatError::TooDifferent { .. }) && err.to_string().contains("F_dm"), "{err}");
}

#[test]
fn clips_on_different_skeletons_are_refused_by_name() {
    let Some(data) = shared_data() else { return };
    let options = AnalysisOptions::default();
    let a = analyse(clip(&data, "cmu/02_02.bvh", 0.01, 2.0), &options, None, None).unwrap();
    let b = analyse(clip(&data, "cmu_daz/02_02.bvh", 0.01, 2.0), &options, None, None).unwrap();
    let err = refusal(concatenate(&a, &b, &ConcatParams::default(), &options));
    assert!(matches!(err, ConcatError::DifferentSkeletons(_)), "{err}");
}

#[test]
fn body_model_puts_the_standing_centre_of_mass_at_a_human_height() {
    let Some(data) = shared_data() else { return };
    // Biomechanics puts the standing centre of mass at 53–58 % of body height; compare it
    // with the highest joint of the same frame (the head's end site, which on some rigs
    // sits at eye level, hence the wider band).
    for name in ["cmu/02_01.bvh", "cmu_daz/05_01.bvh"] {
        let c = clip(&data, name, 0.01, 1.0);
        let a = analyse(c.clone(), &AnalysisOptions::default(), None, None).unwrap();
        assert!(a.model.method.starts_with("de_leva"), "{name}: {}", a.model.method);
        let top = (0..c.joint_count()).map(|j| a.poses.position(0, j).y).fold(f32::MIN, f32::max);
        let ground = (0..c.joint_count()).map(|j| a.poses.position(0, j).y).fold(f32::MAX, f32::min);
        let share = (a.track.com_m[0].y - f64::from(ground)) / f64::from(top - ground);
        assert!((0.50..=0.65).contains(&share), "{name}: centre of mass at {share:.3} of the height");
        // Standing still-ish: momentum small next to a cartwheel's tens of kg·m²/s.
        assert!(a.smoothed[10].length() < 5.0, "{name}: {}", a.smoothed[10].length());
    }
}

/// CMU 90_02's cartwheel joined to itself with the second peak at least 0.8 s after the
/// first, blending in the air: the cartwheel and the join.
fn double_cartwheel(data: &Path) -> (Arc<Clip>, Concatenated) {
    let options = AnalysisOptions::default();
    let c = clip(data, "cmu/90_02.bvh", 1.5, 6.0);
    let a = analyse(c.clone(), &options, None, None).unwrap();
    // A cartwheel ends turned half round: the orientation limit must allow that.
    let params = ConcatParams {
        support: Support::Any,
        min_peak_gap_secs: 0.8,
        max_facing_rad: 150f64.to_radians(),
        ..ConcatParams::default()
    };
    (c, concatenate(&a, &a, &params, &options).unwrap())
}

#[test]
fn a_double_cartwheel_keeps_both_cartwheels_without_a_momentum_spike() {
    let Some(data) = shared_data() else { return };
    let (c, joined) = double_cartwheel(&data);
    let r = &joined.report;
    eprintln!("double cartwheel: {r:?}");
    // Both peaks survive: the result is longer than one cartwheel by about the gap.
    assert!(number(r, "offset_secs") >= 0.8 - 1.0 / c.fps());
    assert!(number(r, "duration_secs") > c.duration_secs() + 0.5);
    // No spike: the smoothed |L| inside the blend stays under the clips' own peaks.
    assert!(
        number(r, "peak_momentum_in_blend") <= number(r, "peak_momentum_first").max(number(r, "peak_momentum_second"))
    );
    // The joined clip is finite everywhere.
    assert!(joined.clip.rotations().iter().all(|q| q.is_finite()));
    assert!(joined.clip.translations().iter().all(|t| t.is_finite()));
}

#[test]
fn walking_has_alternating_stance_phases_and_double_support() {
    let Some(data) = shared_data() else { return };
    for name in ["cmu/02_01.bvh", "cmu/07_01.bvh", "cmu_daz/05_01.bvh"] {
        let c = clip(&data, name, 0.01, 30.0);
        let a = analyse(c.clone(), &AnalysisOptions::default(), None, None).unwrap();
        let frames = c.frame_count() as f64;
        for foot in &a.contacts.feet {
            // Stance takes about 60 % of a walking gait cycle (40 % swing); the thresholds cut
            // a little off heel strike and toe-off.
            let stance: usize = foot.intervals.iter().map(|r| r.len()).sum();
            let share = stance as f64 / frames;
            eprintln!("{name} {}: stance share {share:.2}", foot.foot);
            assert!((0.4..=0.8).contains(&share), "{name} {}: stance share {share:.2}", foot.foot);
            assert!(foot.intervals.len() >= 2, "{name} {}: {:?}", foot.foot, foot.intervals);
        }
        // Double support: both feet down, a minority of the cycle but present every step.
        let double: usize = a.contacts.double_support.iter().map(|r| r.len()).sum();
        let share = double as f64 / frames;
        assert!(!a.contacts.double_support.is_empty() && share < 0.5, "{name}: double support {share:.2}");
        for r in &a.contacts.double_support {
            assert!(a.contacts.feet.iter().all(|f| f.intervals.iter().any(|i| i.start <= r.start && r.end <= i.end)));
        }
    }
}

/// Heights (m) of `joint` at every frame of `clip`, by forward kinematics.
fn heights(clip: &Clip, joint: usize) -> Vec<f32> {
    let poses = kinegraph_nodes::model::forward_kinematics(clip);
    (0..clip.frame_count()).map(|f| poses.frame(f)[joint].translation.y).collect()
}

/// The foot or toe joint that rises highest in `clip`, and that height (m): a kick's
/// effector and its apex.
fn kicking_toe(clip: &Clip) -> (usize, f32) {
    let skeleton = clip.skeleton();
    (0..skeleton.len())
        .filter(|&j| {
            let name = skeleton.joints()[j].name.to_ascii_lowercase();
            name.contains("foot") || name.contains("toe")
        })
        .map(|j| (j, heights(clip, j).into_iter().fold(f32::MIN, f32::max)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap()
}

/// Two front kicks (CMU 144_05) chained by the forward rule with their peaks ≥ 0.5 s
/// apart: both kicks are still there. The kicking toe's apex is read from each source by
/// forward kinematics and looked for in the result: the highest point of the first half
/// of the result and the highest point at least 0.4 s after it each reach 95 % of their
/// source's apex (a window that blends the first kick away leaves 0.31 m of its 0.77 m).
#[test]
fn a_double_kick_keeps_both_kicks_apexes() {
    let Some(data) = shared_data() else { return };
    let (first, second, joined) =
        double_kick(&data, &ConcatParams { min_peak_gap_secs: 0.5, ..ConcatParams::default() });
    let ((toe, apex_first), (toe_second, apex_second)) = (kicking_toe(&first), kicking_toe(&second));
    assert_eq!(toe, toe_second, "the same foot kicks in both");
    let h = heights(&joined.clip, toe);
    let fps = joined.clip.fps();
    let argmax = |range: std::ops::Range<usize>| range.max_by(|&x, &y| h[x].total_cmp(&h[y])).unwrap();
    let p1 = argmax(0..h.len() / 2);
    let p2 = argmax(p1 + (0.4 * fps) as usize..h.len());
    eprintln!(
        "kick apexes: sources {apex_first:.3} m, {apex_second:.3} m; result {:.3} m at {:.2} s, {:.3} m at {:.2} s; {:?}",
        h[p1],
        p1 as f64 / fps,
        h[p2],
        p2 as f64 / fps,
        joined.report
    );
    assert!(h[p1] >= 0.95 * apex_first, "first kick: {} m of {apex_first} m", h[p1]);
    assert!(h[p2] >= 0.95 * apex_second, "second kick: {} m of {apex_second} m", h[p2]);
}

/// Per frame with both neighbours (index `i` is frame `i + 1`), the largest joint
/// acceleration in m/s²: second differences of the forward-kinematics positions times fps².
fn peak_accelerations(clip: &Clip) -> Vec<f64> {
    let poses = kinegraph_nodes::model::forward_kinematics(clip);
    let fps2 = clip.fps() * clip.fps();
    (1..clip.frame_count().saturating_sub(1))
        .map(|f| {
            (0..clip.joint_count())
                .map(|j| {
                    let p = |g: usize| poses.position(g, j).as_dvec3();
                    (p(f + 1) - 2.0 * p(f) + p(f - 1)).length() * fps2
                })
                .fold(0.0, f64::max)
        })
        .collect()
}

/// The largest of `peaks` (per interior frame) over frames `from..=to` (clamped).
fn peak_over(peaks: &[f64], from: isize, to: isize) -> (f64, usize) {
    let (lo, hi) = (from.max(1) as usize, (to.max(1) as usize).min(peaks.len()));
    (lo..=hi).map(|f| (peaks[f - 1], f)).fold((0.0, 0), |b, x| if x.0 > b.0 { x } else { b })
}

/// The double cartwheel's blend is played at half speed (eq. 9's time scaling), and
/// `motion.quality` finds a 29.5× acceleration spike where the window ends. In and 0.25 s
/// around the window, the result's largest joint acceleration (finite differences of FK
/// positions) must stay within 3× of the largest each source clip shows over the frames the
/// window is made from (and 0.25 s around them): the join adds no spike of its own. The
/// spike is the source's: CMU 90_02's left toe tip jumps at frame 218 of the trimmed clip
/// (3996 m/s²), the second copy's last window frame, and replays one frame after the
/// window; its ratio is large only because its neighbourhood is the slowed window. The
/// check pins that down: the peak is the source's own value at the frame it replays.
#[test]
fn a_slowed_blend_window_has_no_acceleration_spike() {
    let Some(data) = shared_data() else { return };
    let (c, joined) = double_cartwheel(&data);
    let r = &joined.report;
    let frame = |key: &str, i: usize| r[key][i].as_i64().unwrap() as isize;
    let (f0, ff) = (frame("window_frames", 0), frame("window_frames", 1));
    let (w0, w1) = (frame("window_after_scaling_frames", 0), frame("window_after_scaling_frames", 1));
    let t = number(r, "offset_frames") as isize;
    assert!(number(r, "time_scale") < 0.75, "the window is slowed: {r:?}");
    let margin = (0.25 * c.fps()).round() as isize;
    let source = peak_accelerations(&c);
    let result = peak_accelerations(&joined.clip);
    let (first_peak, _) = peak_over(&source, f0 - margin, ff);
    let (second_peak, _) = peak_over(&source, f0 - t, ff - t + margin);
    let (peak, at) = peak_over(&result, w0 - margin, w1 + margin);
    let reference = first_peak.max(second_peak);
    eprintln!(
        "window {w0}..={w1}: peak acceleration {peak:.0} m/s² at frame {at}; sources over the frames it plays: \
         {first_peak:.0} and {second_peak:.0} m/s² ({:.2}×)",
        peak / reference
    );
    assert!(peak <= 3.0 * reference, "{peak} m/s² at frame {at} against the sources' {reference} m/s²");
    // Result frame w1 + k plays the second clip's frame ff − t + k (k ≥ 0).
    let replayed = (at as isize - w1 + ff - t) as usize;
    assert!(
        at as isize >= w1 && (peak - source[replayed - 1]).abs() <= 0.01 * peak,
        "{peak} vs {}",
        source[replayed - 1]
    );
}

/// Over each contact of `foot`'s joints (the ankle and every joint below it) that overlaps
/// `window`, the horizontal travel of the stillest of those joints summed frame to frame
/// (cm), the largest; and the deepest any of them goes under y = 0 in those contacts (cm).
fn planted_slide_and_depth_cm(clip: &Clip, foot: &str, window: (usize, usize)) -> (f64, f64) {
    use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
    let poses = kinegraph_nodes::model::forward_kinematics(clip);
    let skeleton = clip.skeleton();
    let ankle = skeleton.index_of(foot).unwrap();
    let joints: Vec<usize> = (0..skeleton.len()).filter(|&j| j == ankle || skeleton.is_ancestor(ankle, j)).collect();
    let (contacts, _) = contacts_of(clip, &poses, &ContactThresholds::default()).unwrap();
    let intervals = &contacts.feet.iter().find(|c| c.foot == foot).unwrap().intervals;
    let (mut slide, mut depth) = (0.0f64, 0.0f64);
    for r in intervals.iter().filter(|r| r.start <= window.1 && r.end > window.0) {
        let moved = (r.start + 1..r.end).map(|f| {
            joints
                .iter()
                .map(|&j| f64::from((poses.position(f, j) - poses.position(f - 1, j)).with_y(0.0).length()))
                .fold(f64::INFINITY, f64::min)
        });
        slide = slide.max(moved.sum::<f64>() * 100.0);
        for f in r.start..r.end {
            depth = depth.max(joints.iter().map(|&j| -f64::from(poses.position(f, j).y) * 100.0).fold(0.0, f64::max));
        }
    }
    (slide, depth)
}

/// The paper's clean-up inside `motion.concat`: in the double kick the standing (left) foot
/// is planted through the whole blend. Measured on the result by forward kinematics and
/// contacts detected on it: over the plants that touch the window the foot slides at most
/// 1 cm (13.7 cm before the clean-up; each source's own standing foot slides 11.8 and
/// 14.9 cm) and goes at most 0.5 cm under the floor (0.71 cm before), and the first kick's
/// toe still reaches 0.7 m. With `foot_lock` off the same join slides, so the check can fail.
#[test]
fn a_double_kick_keeps_its_standing_foot_planted_through_the_blend() {
    let Some(data) = shared_data() else { return };
    let params = ConcatParams { min_peak_gap_secs: 0.5, ..ConcatParams::default() };
    let (first, _, joined) = double_kick(&data, &params);
    let (_, _, raw) = double_kick(&data, &ConcatParams { foot_lock: false, ..params });
    let r = &joined.report;
    let window = |i: usize| r["window_after_scaling_frames"][i].as_u64().unwrap() as usize;
    let window = (window(0), window(1));
    let (slide, depth) = planted_slide_and_depth_cm(&joined.clip, "LeftFoot", window);
    let (raw_slide, raw_depth) = planted_slide_and_depth_cm(&raw.clip, "LeftFoot", window);
    let (toe, _) = kicking_toe(&first);
    let h = heights(&joined.clip, toe);
    let apex = h[..h.len() / 2].iter().copied().fold(f32::MIN, f32::max);
    eprintln!(
        "standing foot over the plants touching the window {window:?}: slide {raw_slide:.2} → {slide:.2} cm, \
         under the floor {raw_depth:.2} → {depth:.2} cm; first kick's toe apex {apex:.3} m"
    );
    assert!(raw_slide > 5.0, "without the clean-up the blend slides the foot: {raw_slide} cm");
    assert!(slide <= 1.0, "the standing foot slides {slide} cm");
    assert!(depth <= 0.5, "the standing foot is {depth} cm under the floor");
    assert!(apex >= 0.7, "the first kick's toe reaches only {apex} m");
}

/// Eq. 9 from outside: the same join with time scaling turned off (bounds 1..1) and no foot
/// clean-up is the plain blend; its whole-body angular momentum, computed again by
/// analysing that clip, gives s = mean of the window's end magnitudes ÷ the window's mean
/// magnitude, which is the time scale the scaled join reports before clamping. Both
/// punch pairs and the double kick.
#[test]
fn the_time_scale_is_eq_9_on_the_blend() {
    let Some(data) = shared_data() else { return };
    let options = AnalysisOptions::default();
    let pairs = [
        (("cmu/79_08.bvh", 2.2, 3.1), ("cmu/79_08.bvh", 3.6, 4.6), Rule::Reverse),
        (("cmu/144_05.bvh", 0.5, 2.2), ("cmu/144_05.bvh", 2.2, 3.9), Rule::Forward),
    ];
    for ((fa, a0, a1), (fb, b0, b1), rule) in pairs {
        let a = analyse(clip(&data, fa, a0, a1), &options, None, None).unwrap();
        let b = analyse(clip(&data, fb, b0, b1), &options, None, None).unwrap();
        let scaled = ConcatParams { rule, ..ConcatParams::default() };
        let plain = ConcatParams { time_scale_range: (1.0, 1.0), foot_lock: false, ..scaled };
        let reported = number(&concatenate(&a, &b, &scaled, &options).unwrap().report, "time_scale_raw");
        let blend = concatenate(&a, &b, &plain, &options).unwrap();
        let window = blend.report["window_frames"].as_array().unwrap().clone();
        let (f0, ff) = (window[0].as_u64().unwrap() as usize, window[1].as_u64().unwrap() as usize);
        let momentum = analyse(Arc::new(blend.clip), &options, None, None).unwrap().smoothed;
        let magnitudes: Vec<f64> = (f0..=ff).map(|f| momentum[f].length()).collect();
        let mean = magnitudes.iter().sum::<f64>() / magnitudes.len() as f64;
        let s = 0.5 * (magnitudes[0] + magnitudes[magnitudes.len() - 1]) / mean;
        eprintln!("{fa} {a0}-{a1} s + {fb} {b0}-{b1} s: window {f0}..={ff}, eq. 9 here {s:.6}, reported {reported:.6}");
        assert!((s - reported).abs() < 1e-6 * reported.abs().max(1.0), "eq. 9 gives {s}, the join reports {reported}");
    }
}
