//! The viewport: the selected node's clip output as a skeleton, drawn with egui's painter
//! in an orthographic side or front view, with play/pause and a frame slider.
//!
//! Steps: 1. forward kinematics once per clip (kept while the same `Arc<Clip>` is shown);
//! 2. the bounding box of every joint over every frame fixes the scale, so the figure
//! does not jump while playing; 3. each frame draws a line from every joint to its parent.

use std::sync::Arc;

use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui, Vec2};
use glam::Vec3;
use kinegraph_nodes::model::{Clip, ClipPoses, forward_kinematics};

/// Which plane the orthographic camera looks at (Y up, metres).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum View {
    /// Looking along −X: Z to the right.
    Side,
    /// Looking along −Z: X to the right.
    Front,
}

/// Playback state and the FK of the clip on show.
pub(crate) struct Viewport {
    playing: bool,
    time_secs: f64,
    view: View,
    shown: Option<(Arc<Clip>, ClipPoses, Vec3, Vec3)>,
}

impl Default for Viewport {
    fn default() -> Self {
        Viewport { playing: true, time_secs: 0.0, view: View::Side, shown: None }
    }
}

impl Viewport {
    /// Draws `clip` (or a hint when there is none).
    pub(crate) fn show(&mut self, ui: &mut Ui, title: &str, clip: Option<&Arc<Clip>>) {
        let Some(clip) = clip else {
            self.shown = None;
            ui.centered_and_justified(|ui| {
                ui.label(egui::RichText::new("Select a node with a clip output to play it here.").weak());
            });
            return;
        };
        if !self.shown.as_ref().is_some_and(|(c, ..)| Arc::ptr_eq(c, clip)) {
            let poses = forward_kinematics(clip);
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for f in 0..poses.frame_count() {
                for t in poses.frame(f) {
                    lo = lo.min(t.translation);
                    hi = hi.max(t.translation);
                }
            }
            self.shown = Some((clip.clone(), poses, lo, hi));
        }
        let frames = clip.frame_count();
        let fps = clip.fps().max(1e-6);
        let duration = frames as f64 / fps;
        if self.playing && frames > 1 {
            let dt = f64::from(ui.input(|i| i.stable_dt).min(0.1));
            self.time_secs = (self.time_secs + dt) % duration.max(1e-6);
            ui.ctx().request_repaint();
        }
        let mut frame = ((self.time_secs * fps) as usize).min(frames.saturating_sub(1));
        ui.horizontal(|ui| {
            ui.label(egui::RichText::new(title).strong());
            if ui.button(if self.playing { "pause" } else { "play" }).clicked() {
                self.playing = !self.playing;
            }
            let slider = ui.add(egui::Slider::new(&mut frame, 0..=frames.saturating_sub(1)).text("frame"));
            if slider.changed() {
                self.playing = false;
                self.time_secs = frame as f64 / fps;
            }
            ui.label(format!("{:.2} s / {:.2} s @ {fps:.0} fps", frame as f64 / fps, duration));
            ui.selectable_value(&mut self.view, View::Side, "side");
            ui.selectable_value(&mut self.view, View::Front, "front");
        });
        let Some((_, poses, lo, hi)) = &self.shown else { return };
        let (response, painter) = ui.allocate_painter(ui.available_size().max(Vec2::splat(50.0)), Sense::hover());
        let rect = response.rect;
        painter.rect_filled(rect, 4.0, Color32::from_gray(24));
        if poses.frame_count() == 0 {
            return;
        }
        let project = |p: Vec3| -> Vec2 {
            match self.view {
                View::Side => Vec2::new(p.z, p.y),
                View::Front => Vec2::new(p.x, p.y),
            }
        };
        let (plo, phi) = (project(*lo), project(*hi));
        let to_screen = fit(rect.shrink(16.0), plo, phi);
        // Ground line at y = 0 when it is in view.
        let ground = to_screen(Vec2::new(plo.x, 0.0)).y;
        if rect.y_range().contains(ground) {
            painter.line_segment(
                [Pos2::new(rect.left(), ground), Pos2::new(rect.right(), ground)],
                Stroke::new(1.0, Color32::from_gray(70)),
            );
        }
        let pose = poses.frame(frame.min(poses.frame_count() - 1));
        let stroke = Stroke::new(2.0, Color32::from_rgb(230, 230, 210));
        for (j, joint) in clip.skeleton().joints().iter().enumerate() {
            let here = to_screen(project(pose[j].translation));
            if let Some(parent) = joint.parent {
                painter.line_segment([to_screen(project(pose[parent].translation)), here], stroke);
            }
            painter.circle_filled(here, 2.5, Color32::from_rgb(80, 170, 255));
        }
    }
}

/// Maps the box `lo..hi` (metres, Y up) into `rect` keeping the aspect ratio.
fn fit(rect: Rect, lo: Vec2, hi: Vec2) -> impl Fn(Vec2) -> Pos2 {
    let size = (hi - lo).max(Vec2::splat(1e-3));
    let scale = (rect.width() / size.x).min(rect.height() / size.y);
    let centre = (lo + hi) * 0.5;
    let screen_centre = rect.center();
    move |p: Vec2| Pos2::new(screen_centre.x + (p.x - centre.x) * scale, screen_centre.y - (p.y - centre.y) * scale)
}
