//! The viewport: the selected node's clip as a skeleton in 3-D (perspective, Y up, metres),
//! drawn with egui's painter, with its mesh when it has one (a baked mesh sequence, or a
//! skinned mesh posed by linear blend skinning), a timeline, an orbit camera, a ground grid,
//! the root and foot trajectories, foot contacts, and a second clip pinned beside it for
//! comparison; smoke (a volume sequence) as its marker particles, on the same clock.
//!
//! Steps: 1. forward kinematics and foot contacts once per clip (kept while the same
//! `Arc<Clip>` is shown); 2. the bounding box of every joint over every frame frames the
//! camera and places the grid at the lowest point the clip reaches, so nothing jumps while
//! playing; 3. each frame projects every bone through the camera and draws it, after the
//! mesh: its triangles shaded by their facing to the camera and drawn far to near.

use std::borrow::Cow;
use std::sync::Arc;

use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui, Vec2};
use glam::Vec3;
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::skinning::{blend_matrices, check_skin, skinning_matrices};
use kinegraph_nodes::model::{
    BodyPose, BodyShape, Clip, ClipPoses, Contacts, Curves, Mesh, MeshSequence, VolumeSequence, forward_kinematics,
};

/// Vertical field of view of the camera (radians).
const FOV_Y: f32 = 0.8;
/// Grid spacing (metres).
const GRID_STEP_M: f32 = 0.5;
/// Playback speeds offered.
const SPEEDS: [f32; 5] = [0.1, 0.25, 0.5, 1.0, 2.0];

const BONE: Color32 = Color32::from_rgb(230, 230, 210);
const JOINT: Color32 = Color32::from_rgb(80, 170, 255);
const COMPARED: Color32 = Color32::from_rgb(255, 150, 60);
const CONTACT: Color32 = Color32::from_rgb(90, 220, 120);
const SKIN: Color32 = Color32::from_rgb(150, 140, 130);
/// Fixed objects of the scene (props).
const PROP: Color32 = Color32::from_rgb(140, 105, 70);
/// Half the side of a smoke particle's square, points.
const PARTICLE_HALF: f32 = 1.2;
/// The centre of mass's path on the ground and in flight.
const COM_GROUND: Color32 = Color32::from_rgb(120, 170, 120);
const COM_FLIGHT: Color32 = Color32::from_rgb(90, 230, 230);
/// Free bodies in the smoke.
const BODY: Color32 = Color32::from_rgb(230, 200, 90);

/// What a node gives the viewport to play: a clip with the mesh that moves with it, and
/// smoke; any of them may be missing.
#[derive(Clone, Default)]
pub(crate) struct Motion {
    pub(crate) clip: Option<Arc<Clip>>,
    pub(crate) mesh: Option<ShownMesh>,
    pub(crate) smoke: Option<Arc<VolumeSequence>>,
    /// Time ranges marked under the timeline (phases, stages, controllers, transitions,
    /// blend windows).
    pub(crate) bands: Vec<super::results::Band>,
    /// Curves with the centre of mass's path (`com.x/y/z`, metres), drawn over the clip.
    pub(crate) com: Option<Arc<Curves>>,
    /// Fixed objects of the scene (a stool), drawn where they stand with the clip.
    pub(crate) props: Option<Arc<Mesh>>,
}

impl Motion {
    /// Whether there is nothing to play (a mesh needs its clip).
    pub(crate) fn is_empty(&self) -> bool {
        self.clip.is_none() && self.smoke.is_none()
    }
}

/// The frame of a sequence at `fps` with `frame_count` frames shown at `time_secs`: frame
/// `f` covers [f/fps, (f+1)/fps); held at the last frame past the end.
fn frame_at(time_secs: f64, fps: f64, frame_count: usize) -> usize {
    ((time_secs * fps).max(0.0) as usize).min(frame_count.saturating_sub(1))
}

/// Smoke ready to draw: its volumes and the box of its voxel grid (metres).
struct ShownSmoke {
    volumes: Arc<VolumeSequence>,
    lo: Vec3,
    hi: Vec3,
}

impl ShownSmoke {
    fn new(volumes: &Arc<VolumeSequence>) -> Self {
        let grid = volumes.grid;
        let half = Vec3::splat(grid.voxel_m * 0.5);
        let (lo, hi) = if grid.is_empty() {
            (Vec3::ZERO, Vec3::ONE)
        } else {
            (grid.centre_m(0) - half, grid.centre_m(grid.len() - 1) + half)
        };
        ShownSmoke { volumes: volumes.clone(), lo, hi }
    }

    /// Seconds the frames last at their own rate.
    fn duration_secs(&self) -> f64 {
        self.volumes.frames.len() as f64 / self.volumes.fps.max(1e-6)
    }

    fn frame_at(&self, time_secs: f64) -> usize {
        frame_at(time_secs, self.volumes.fps, self.volumes.frames.len())
    }
}

/// The smoke frame the viewport drew last: how many of its particles were on screen, and
/// where its free bodies' centres were.
#[derive(Clone, Debug, PartialEq)]
pub struct SmokeDrawn {
    /// Frame index in the volume sequence.
    pub frame: usize,
    /// Particles drawn (those in front of the camera).
    pub particles: usize,
    /// Screen position of each body's centre, in the order of the frame's bodies (`None`
    /// behind the camera).
    pub bodies: Vec<Option<Pos2>>,
}

/// A mesh that moves with the clip on show.
#[derive(Clone)]
pub(crate) enum ShownMesh {
    /// Deformed per frame by a node (skinning, bar-net): frame `f` goes with clip frame `f`.
    Baked(Arc<MeshSequence>),
    /// Skinned to the clip's skeleton: posed here by linear blend skinning.
    Skinned(Arc<Mesh>),
}

impl ShownMesh {
    /// Whether the mesh can move with `clip`: a sequence of that clip's frames, or a skin
    /// bound to its skeleton. Checked once, when the mesh is put on show.
    fn fits(&self, clip: &Clip) -> bool {
        match self {
            ShownMesh::Baked(seq) => seq.frame_count() >= clip.frame_count(),
            ShownMesh::Skinned(mesh) => {
                mesh.skin.as_ref().is_some_and(|skin| check_skin(skin, clip.skeleton(), mesh.positions.len()).is_ok())
            }
        }
    }

    /// The same mesh (the same shared data).
    fn is(&self, other: &ShownMesh) -> bool {
        match (self, other) {
            (ShownMesh::Baked(a), ShownMesh::Baked(b)) => Arc::ptr_eq(a, b),
            (ShownMesh::Skinned(a), ShownMesh::Skinned(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }

    /// The mesh's vertex positions (metres) at `frame` of its clip posed as `poses` (the mesh
    /// fits the clip), with the mesh whose triangles they fill.
    fn positions(&self, poses: &ClipPoses, frame: usize) -> (Cow<'_, [Vec3]>, &Mesh) {
        match self {
            ShownMesh::Baked(seq) => (Cow::Borrowed(seq.frame_positions(frame)), seq.rest.as_ref()),
            ShownMesh::Skinned(mesh) => {
                let Some(skin) = &mesh.skin else { return (Cow::Borrowed(&mesh.positions), mesh.as_ref()) };
                // Positions only: the drawing shades by face normals.
                let matrices = skinning_matrices(poses.frame(frame), &skin.inverse_bind_matrices);
                let posed = (mesh.positions.iter().zip(&skin.joints).zip(&skin.weights))
                    .map(|((p, joints), weights)| blend_matrices(&matrices, joints, weights).transform_point3(*p))
                    .collect();
                (Cow::Owned(posed), mesh.as_ref())
            }
        }
    }
}

/// An orbit camera around `target`: `yaw` about +Y from +Z, `pitch` above the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Camera {
    /// Radians; 0 looks along −Z (the front of a CMU clip).
    pub(crate) yaw: f32,
    /// Radians, kept inside ±89°.
    pub(crate) pitch: f32,
    /// Metres from the target.
    pub(crate) distance: f32,
    /// The point orbited (metres).
    pub(crate) target: Vec3,
}

impl Default for Camera {
    fn default() -> Self {
        Camera { yaw: 0.6, pitch: 0.35, distance: 5.0, target: Vec3::new(0.0, 1.0, 0.0) }
    }
}

impl Camera {
    const MAX_PITCH: f32 = 1.55;

    /// Where the camera is.
    pub(crate) fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + self.distance * Vec3::new(cp * sy, sp, cp * cy)
    }

    /// Looks at the box `lo..hi` from the current direction, close enough to see all of it.
    pub(crate) fn frame(&mut self, lo: Vec3, hi: Vec3, aspect: f32) {
        self.target = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(0.1);
        let half_fov = (FOV_Y * 0.5).min(((FOV_Y * 0.5).tan() * aspect.max(0.1)).atan());
        self.distance = radius / half_fov.sin() * 1.05;
    }

    /// Turns the camera by a pointer drag (points).
    pub(crate) fn orbit(&mut self, drag: Vec2) {
        self.yaw -= drag.x * 0.008;
        self.pitch = (self.pitch + drag.y * 0.008).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
    }

    /// Slides the target in the view plane so the ground follows the pointer.
    pub(crate) fn pan(&mut self, drag: Vec2, viewport_height: f32) {
        let metres_per_point = 2.0 * self.distance * (FOV_Y * 0.5).tan() / viewport_height.max(1.0);
        let (right, up, _) = self.basis();
        self.target += (-drag.x * right + drag.y * up) * metres_per_point;
    }

    /// Moves towards the target by a scroll amount (points; positive = closer).
    pub(crate) fn zoom(&mut self, scroll: f32) {
        self.distance = (self.distance * (-scroll * 0.002).exp()).clamp(0.05, 1e4);
    }

    /// The camera's right, up and forward unit vectors.
    fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye()).normalize_or_zero();
        let right = forward.cross(Vec3::Y).normalize_or_zero();
        (right, right.cross(forward), forward)
    }

    /// World → screen for a viewport `rect` (a pinhole camera with [`FOV_Y`]); `None` for
    /// points behind the camera.
    pub(crate) fn projector(&self, rect: Rect) -> impl Fn(Vec3) -> Option<Pos2> + use<> {
        let (eye, (right, up, forward)) = (self.eye(), self.basis());
        let points_per_unit = rect.height() * 0.5 / (FOV_Y * 0.5).tan();
        let centre = rect.center();
        move |p: Vec3| {
            let d = p - eye;
            let depth = d.dot(forward);
            (depth > 1e-3).then(|| {
                let s = points_per_unit / depth;
                Pos2::new(centre.x + d.dot(right) * s, centre.y - d.dot(up) * s)
            })
        }
    }
}

/// A clip ready to draw: its poses, bounds, root and foot tracks and contacts.
struct Shown {
    clip: Arc<Clip>,
    title: String,
    poses: ClipPoses,
    lo: Vec3,
    hi: Vec3,
    /// Foot contacts: the graph's own for this clip when it computed them, else found here
    /// with the default thresholds when the feet are found by joint name.
    contacts: Option<Contacts>,
    /// The graph's contacts in use, if any (so they are taken once).
    graph_contacts: Option<Arc<Contacts>>,
    /// Joint indices of the feet (left, right), matching `contacts.feet`.
    feet: Vec<usize>,
    /// The mesh offered with the clip, and whether it fits it (drawn only then).
    mesh: Option<ShownMesh>,
    mesh_fits: bool,
}

impl Shown {
    fn new(clip: &Arc<Clip>, title: &str) -> Self {
        let poses = forward_kinematics(clip);
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for f in 0..poses.frame_count() {
            for t in poses.frame(f) {
                lo = lo.min(t.translation);
                hi = hi.max(t.translation);
            }
        }
        if poses.frame_count() == 0 || clip.skeleton().joints().is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        }
        let found = contacts_of(clip, &poses, &ContactThresholds::default()).ok();
        let feet = found.as_ref().map(|(_, feet)| feet.to_vec()).unwrap_or_default();
        Shown {
            clip: clip.clone(),
            title: title.to_string(),
            poses,
            lo,
            hi,
            contacts: found.map(|(c, _)| c),
            graph_contacts: None,
            feet,
            mesh: None,
            mesh_fits: false,
        }
    }

    /// Shows `contacts`, computed by the graph for this clip, instead of the viewport's own
    /// guess: when they cover the clip's frames and name its joints.
    fn use_graph_contacts(&mut self, contacts: &Arc<Contacts>) {
        if self.graph_contacts.as_ref().is_some_and(|c| Arc::ptr_eq(c, contacts))
            || contacts.frame_count != self.clip.frame_count()
        {
            return;
        }
        let feet: Option<Vec<usize>> = contacts.feet.iter().map(|f| self.clip.skeleton().index_of(&f.foot)).collect();
        if let Some(feet) = feet {
            self.contacts = Some((**contacts).clone());
            self.feet = feet;
            self.graph_contacts = Some(contacts.clone());
        }
    }

    fn duration_secs(&self) -> f64 {
        self.clip.frame_count() as f64 / self.clip.fps().max(1e-6)
    }

    /// The frame shown at `time_secs` (held at the last frame past the end).
    fn frame_at(&self, time_secs: f64) -> usize {
        frame_at(time_secs, self.clip.fps(), self.poses.frame_count())
    }

    fn in_contact(&self, foot: usize, frame: usize) -> bool {
        self.contacts
            .as_ref()
            .and_then(|c| c.feet.get(foot))
            .is_some_and(|f| f.intervals.iter().any(|r| r.contains(frame)))
    }
}

/// What the viewport draws besides the skeleton.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Overlays {
    mesh: bool,
    grid: bool,
    trajectories: bool,
    contacts: bool,
    smoke: bool,
}

/// Playback state, camera, the clip on show and the clip pinned for comparison.
pub(crate) struct Viewport {
    playing: bool,
    looping: bool,
    speed: f32,
    time_secs: f64,
    camera: Camera,
    /// Frame the camera on the next draw (a new clip, or the user asked).
    reframe: bool,
    overlays: Overlays,
    shown: Option<Shown>,
    compared: Option<Shown>,
    smoke: Option<ShownSmoke>,
    /// What the last draw showed of the smoke.
    smoke_drawn: Option<SmokeDrawn>,
    /// Where the last draw put the centre of mass at the time shown (screen), if it drew one.
    com_drawn: Option<Pos2>,
    /// How many triangles of props the last draw filled.
    props_drawn: usize,
}

impl Default for Viewport {
    fn default() -> Self {
        Viewport {
            playing: true,
            looping: true,
            speed: 1.0,
            time_secs: 0.0,
            camera: Camera::default(),
            reframe: true,
            overlays: Overlays { mesh: true, grid: true, trajectories: true, contacts: true, smoke: true },
            shown: None,
            compared: None,
            smoke: None,
            smoke_drawn: None,
            com_drawn: None,
            props_drawn: 0,
        }
    }
}

impl Viewport {
    /// The time shown (seconds).
    pub(crate) fn time_secs(&self) -> f64 {
        self.time_secs
    }

    /// Whether it is playing.
    pub(crate) fn is_playing(&self) -> bool {
        self.playing
    }

    /// Shows time `secs` (seconds), paused, as a drag of the time slider does.
    pub(crate) fn seek(&mut self, secs: f64) {
        self.time_secs = secs;
        self.playing = false;
    }

    /// The foot contacts shown with the played clip, if any.
    pub(crate) fn contacts(&self) -> Option<&Contacts> {
        self.shown.as_ref()?.contacts.as_ref()
    }

    /// The smoke frame drawn last and its particles on screen, if smoke was drawn.
    pub(crate) fn smoke_drawn(&self) -> Option<SmokeDrawn> {
        self.smoke_drawn.clone()
    }

    /// How many triangles of props the last draw filled.
    pub(crate) fn props_drawn(&self) -> usize {
        self.props_drawn
    }

    /// Where the centre of mass was drawn last at the time shown (screen), if it was.
    pub(crate) fn com_drawn(&self) -> Option<Pos2> {
        self.com_drawn
    }

    /// Draws the `motion`'s clip and mesh and its smoke (or a hint when there is none), with
    /// the timeline above; `contacts` are the graph's own for this clip, if it computed them.
    pub(crate) fn show(&mut self, ui: &mut Ui, title: &str, motion: Motion, contacts: Option<&Arc<Contacts>>) {
        let Motion { clip, mesh, smoke, bands: motion_bands, com, props } = motion;
        self.com_drawn = None;
        self.props_drawn = 0;
        match &smoke {
            Some(v) if !self.smoke.as_ref().is_some_and(|s| Arc::ptr_eq(&s.volumes, v)) => {
                self.reframe |= self.smoke.is_none();
                self.smoke = Some(ShownSmoke::new(v));
            }
            Some(_) => {}
            None => self.smoke = None,
        }
        self.smoke_drawn = None;
        match clip.as_ref() {
            Some(clip) if !self.shown.as_ref().is_some_and(|s| Arc::ptr_eq(&s.clip, clip)) => {
                let first = self.shown.is_none();
                self.shown = Some(Shown::new(clip, title));
                self.reframe |= first;
            }
            Some(_) => {}
            None => self.shown = None,
        }
        if let Some(shown) = &mut self.shown {
            if let Some(contacts) = contacts {
                shown.use_graph_contacts(contacts);
            }
            let same = match (&shown.mesh, &mesh) {
                (Some(a), Some(b)) => a.is(b),
                (a, b) => a.is_none() && b.is_none(),
            };
            if !same {
                shown.mesh_fits = mesh.as_ref().is_some_and(|m| m.fits(&shown.clip));
                shown.mesh = mesh;
            }
        }
        if self.shown.is_none() && self.compared.is_none() && self.smoke.is_none() {
            ui.centered_and_justified(|ui| {
                ui.label(egui::RichText::new("Select a node with a clip or smoke output to play it here.").weak());
            });
            return;
        }
        let duration = (self.shown.iter().chain(&self.compared).map(Shown::duration_secs))
            .chain(self.smoke.as_ref().map(ShownSmoke::duration_secs))
            .fold(0.0, f64::max);
        self.advance(ui, duration);
        self.timeline(ui, duration);
        self.contact_strip(ui);
        self.band_strip(ui, &motion_bands, duration);
        let (response, painter) =
            ui.allocate_painter(ui.available_size().max(Vec2::splat(50.0)), Sense::click_and_drag());
        let rect = response.rect;
        self.steer_camera(ui, &response);
        if self.reframe {
            let (lo, hi) = self.bounds();
            self.camera.frame(lo, hi, rect.width() / rect.height().max(1.0));
            self.reframe = false;
        }
        painter.rect_filled(rect, 4.0, Color32::from_gray(24));
        let project = self.camera.projector(rect);
        let painter = painter.with_clip_rect(rect);
        let floor = self.bounds().0.y;
        if self.overlays.grid {
            draw_grid(&painter, &project, self.bounds(), floor);
        }
        for (k, (shown, colour)) in
            self.shown.iter().map(|s| (s, BONE)).chain(self.compared.iter().map(|s| (s, COMPARED))).enumerate()
        {
            if self.overlays.mesh {
                // The props stand with the clip on show (not with one pinned for comparison).
                let props = props.as_deref().filter(|_| k == 0 && self.shown.is_some());
                let drawn =
                    draw_mesh(&painter, &project, self.camera.eye(), shown, shown.frame_at(self.time_secs), props);
                if props.is_some() {
                    self.props_drawn = drawn;
                }
            }
            if self.overlays.trajectories {
                draw_trajectories(&painter, &project, shown, floor, colour);
            }
            draw_skeleton(&painter, &project, shown, shown.frame_at(self.time_secs), colour, self.overlays.contacts);
        }
        if let Some(com) = com.as_ref().filter(|_| self.overlays.trajectories) {
            self.com_drawn = draw_com_path(&painter, &project, com, self.time_secs);
        }
        if let Some(smoke) = self.smoke.as_ref().filter(|_| self.overlays.smoke) {
            let frame = smoke.frame_at(self.time_secs);
            let particles = draw_smoke(&painter, &project, &smoke.volumes, frame);
            let bodies = smoke.volumes.frames.get(frame).map_or(&[][..], |f| &f.bodies[..]);
            let bodies = bodies.iter().map(|b| draw_body(&painter, &project, b)).collect();
            self.smoke_drawn = Some(SmokeDrawn { frame, particles, bodies });
        }
    }

    /// Moves the clock on while playing; stops at the end unless looping.
    fn advance(&mut self, ui: &Ui, duration: f64) {
        if !self.playing || duration <= 0.0 {
            return;
        }
        let dt = f64::from(ui.input(|i| i.stable_dt).min(0.1) * self.speed);
        self.time_secs += dt;
        if self.time_secs >= duration {
            if self.looping {
                self.time_secs %= duration;
            } else {
                self.time_secs = duration;
                self.playing = false;
            }
        }
        ui.ctx().request_repaint();
    }

    fn timeline(&mut self, ui: &mut Ui, duration: f64) {
        ui.horizontal(|ui| {
            let title = self.shown.as_ref().map_or("", |s| s.title.as_str());
            ui.label(egui::RichText::new(title).strong());
            if ui.button(if self.playing { "pause" } else { "play" }).clicked() {
                if !self.playing && self.time_secs >= duration {
                    self.time_secs = 0.0;
                }
                self.playing = !self.playing;
            }
            let mut time = self.time_secs;
            ui.spacing_mut().slider_width = (ui.available_width() - 440.0).max(120.0);
            let slider = ui.add(egui::Slider::new(&mut time, 0.0..=duration.max(1e-3)).suffix(" s").text("time"));
            if slider.changed() {
                self.playing = false;
                self.time_secs = time;
            }
            if let Some(s) = &self.shown {
                ui.label(format!("frame {} @ {:.0} fps", s.frame_at(self.time_secs), s.clip.fps()));
            }
            if let Some(s) = &self.smoke {
                ui.label(format!("smoke frame {} @ {:.0} fps", s.frame_at(self.time_secs), s.volumes.fps));
            }
            egui::ComboBox::from_id_salt("kg_speed").selected_text(format!("{}×", self.speed)).width(54.0).show_ui(
                ui,
                |ui| {
                    for s in SPEEDS {
                        ui.selectable_value(&mut self.speed, s, format!("{s}×"));
                    }
                },
            );
            ui.checkbox(&mut self.looping, "loop");
        });
        ui.horizontal(|ui| {
            ui.label("view");
            for (label, yaw, pitch) in
                [("front", 0.0, 0.05), ("side", std::f32::consts::FRAC_PI_2, 0.05), ("top", 0.0, 1.5)]
            {
                if ui.button(label).clicked() {
                    (self.camera.yaw, self.camera.pitch) = (yaw, pitch);
                    self.reframe = true;
                }
            }
            if ui.button("frame").on_hover_text("fit the clip in view (or double-click the view)").clicked() {
                self.reframe = true;
            }
            ui.separator();
            if self.shown.as_ref().is_some_and(|s| s.mesh_fits) {
                ui.checkbox(&mut self.overlays.mesh, "mesh");
            }
            if self.smoke.is_some() {
                ui.checkbox(&mut self.overlays.smoke, "smoke");
            }
            ui.checkbox(&mut self.overlays.grid, "grid");
            ui.checkbox(&mut self.overlays.trajectories, "trails");
            ui.checkbox(&mut self.overlays.contacts, "contacts");
            ui.separator();
            if let Some(shown) = &self.shown
                && ui
                    .button("pin to compare")
                    .on_hover_text("keep this clip on show, in orange, to compare others with it")
                    .clicked()
            {
                self.compared = Some(Shown::new(&shown.clip, &shown.title));
            }
            if let Some(c) = &self.compared {
                ui.colored_label(COMPARED, format!("comparing with {}", c.title));
                if ui.button("unpin").clicked() {
                    self.compared = None;
                }
            }
        });
    }

    /// Each foot's contacts as bars along the clip's time, with the current time marked.
    /// The marked time ranges along the timeline, named on hover, with the playhead.
    fn band_strip(&self, ui: &mut Ui, bands: &[super::results::Band], duration: f64) {
        if bands.is_empty() || duration <= 0.0 {
            return;
        }
        ui.horizontal(|ui| {
            ui.add_sized([90.0, 12.0], egui::Label::new(egui::RichText::new("markers").small()));
            let (rect, response) = ui.allocate_exact_size(Vec2::new(ui.available_width(), 10.0), Sense::hover());
            let painter = ui.painter();
            painter.rect_filled(rect, 2.0, Color32::from_gray(40));
            let x = |secs: f64| rect.left() + rect.width() * (secs / duration).clamp(0.0, 1.0) as f32;
            let mut hovered = None;
            for b in bands {
                let cell =
                    Rect::from_x_y_ranges(x(b.start_secs)..=x(b.end_secs).max(x(b.start_secs) + 1.0), rect.y_range());
                painter.rect_filled(cell, 1.0, super::results::band_colour(&b.name, 200));
                if response.hover_pos().is_some_and(|p| cell.contains(p)) {
                    hovered = Some(b);
                }
            }
            let t = x(self.time_secs);
            painter.line_segment(
                [Pos2::new(t, rect.top()), Pos2::new(t, rect.bottom())],
                Stroke::new(1.5, Color32::WHITE),
            );
            if let Some(b) = hovered {
                response.on_hover_text(format!("{}: {:.2} – {:.2} s", b.name, b.start_secs, b.end_secs));
            }
        });
    }

    fn contact_strip(&self, ui: &mut Ui) {
        let Some(shown) = &self.shown else { return };
        let Some(contacts) = shown.contacts.as_ref().filter(|_| self.overlays.contacts) else { return };
        let frames = contacts.frame_count.max(1) as f32;
        for foot in &contacts.feet {
            ui.horizontal(|ui| {
                ui.add_sized([90.0, 12.0], egui::Label::new(egui::RichText::new(&foot.foot).small()).truncate());
                let (rect, _) = ui.allocate_exact_size(Vec2::new(ui.available_width(), 8.0), Sense::hover());
                let painter = ui.painter();
                painter.rect_filled(rect, 2.0, Color32::from_gray(40));
                for r in &foot.intervals {
                    let x0 = rect.left() + rect.width() * r.start as f32 / frames;
                    let x1 = rect.left() + rect.width() * r.end as f32 / frames;
                    painter.rect_filled(Rect::from_x_y_ranges(x0..=x1, rect.y_range()), 1.0, CONTACT);
                }
                let x = rect.left() + rect.width() * shown.frame_at(self.time_secs) as f32 / frames;
                painter.line_segment(
                    [Pos2::new(x, rect.top()), Pos2::new(x, rect.bottom())],
                    Stroke::new(1.5, Color32::WHITE),
                );
            });
        }
    }

    fn steer_camera(&mut self, ui: &Ui, response: &egui::Response) {
        let pan = response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || (response.dragged_by(egui::PointerButton::Primary) && ui.input(|i| i.modifiers.shift));
        if pan {
            self.camera.pan(response.drag_delta(), response.rect.height());
        } else if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(response.drag_delta());
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom(scroll);
            }
        }
        if response.double_clicked() {
            self.reframe = true;
        }
    }

    /// The box around both clips and the smoke's grid on show.
    fn bounds(&self) -> (Vec3, Vec3) {
        (self.shown.iter().chain(&self.compared).map(|s| (s.lo, s.hi)))
            .chain(self.smoke.iter().map(|s| (s.lo, s.hi)))
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
            .unwrap_or((Vec3::ZERO, Vec3::ONE))
    }
}

/// Grid lines every [`GRID_STEP_M`] on the floor under the clip, one metre beyond it, with the
/// world X (red) and Z (blue) axes through the origin when they cross it.
fn draw_grid(painter: &egui::Painter, project: &impl Fn(Vec3) -> Option<Pos2>, (lo, hi): (Vec3, Vec3), floor: f32) {
    let snap = |v: f32, up: bool| if up { (v / GRID_STEP_M).ceil() } else { (v / GRID_STEP_M).floor() } * GRID_STEP_M;
    let (x0, x1) = (snap(lo.x - 1.0, false), snap(hi.x + 1.0, true));
    let (z0, z1) = (snap(lo.z - 1.0, false), snap(hi.z + 1.0, true));
    let line = |a: Vec3, b: Vec3, colour: Color32| {
        if let (Some(a), Some(b)) = (project(a), project(b)) {
            painter.line_segment([a, b], Stroke::new(1.0, colour));
        }
    };
    let steps = |from: f32, to: f32| {
        (0..=((to - from) / GRID_STEP_M).round() as i32).map(move |i| from + i as f32 * GRID_STEP_M)
    };
    for x in steps(x0, x1) {
        let colour = if x.abs() < 1e-4 { Color32::from_rgb(70, 90, 160) } else { Color32::from_gray(50) };
        line(Vec3::new(x, floor, z0), Vec3::new(x, floor, z1), colour);
    }
    for z in steps(z0, z1) {
        let colour = if z.abs() < 1e-4 { Color32::from_rgb(160, 70, 70) } else { Color32::from_gray(50) };
        line(Vec3::new(x0, floor, z), Vec3::new(x1, floor, z), colour);
    }
}

/// The root's path on the floor and each foot's path, over the whole clip.
fn draw_trajectories(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    shown: &Shown,
    floor: f32,
    colour: Color32,
) {
    let frames = shown.poses.frame_count();
    let mut tracks = vec![(0, true)];
    tracks.extend(shown.feet.iter().map(|&f| (f, false)));
    for (joint, on_floor) in tracks {
        if joint >= shown.clip.skeleton().joints().len() {
            continue;
        }
        let points: Vec<Pos2> = (0..frames)
            .filter_map(|f| {
                let p = shown.poses.position(f, joint);
                project(if on_floor { Vec3::new(p.x, floor, p.z) } else { p })
            })
            .collect();
        painter.add(egui::Shape::line(points, Stroke::new(1.0, colour.gamma_multiply(0.35))));
    }
}

/// The centre of mass's path from `curves` (`com.x/y/z`, metres): ground frames dim, flight
/// frames bright with their fitted parabola (`com.y ballistic`) dotted beside them, and a
/// dot where it is at `time_secs`; returns that dot's place on screen.
fn draw_com_path(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    curves: &Curves,
    time_secs: f64,
) -> Option<Pos2> {
    let channel = |name: &str| curves.channel(name).map(|c| c.values.as_slice());
    let (Some(x), Some(y), Some(z)) = (channel("com.x"), channel("com.y"), channel("com.z")) else { return None };
    let flight = |f: usize| channel("flight").is_some_and(|v| v.get(f).is_some_and(|&v| v > 0.5));
    let at = |f: usize, y: &[f64]| Vec3::new(x[f] as f32, y[f] as f32, z[f] as f32);
    let frames = x.len().min(y.len()).min(z.len());
    for f in 1..frames {
        let colour = if flight(f) { COM_FLIGHT } else { COM_GROUND };
        if let (Some(a), Some(b)) = (project(at(f - 1, y)), project(at(f, y))) {
            painter.line_segment([a, b], Stroke::new(2.0, colour));
        }
    }
    if let Some(fitted) = channel("com.y ballistic").filter(|v| v.len() >= frames) {
        let dots: Vec<egui::Shape> = (0..frames)
            .filter(|&f| flight(f))
            .filter_map(|f| project(at(f, fitted)))
            .map(|p| egui::Shape::circle_filled(p, 1.5, Color32::WHITE))
            .collect();
        painter.extend(dots);
    }
    let now = project(at(frame_at(time_secs, curves.fps(), frames), y))?;
    painter.circle(now, 4.0, COM_FLIGHT, Stroke::new(1.0, Color32::BLACK));
    Some(now)
}

/// The shown clip's mesh at `frame` and the scene's `props`, sorted together far to near
/// (painter's order, so a stool hides the hips seen from behind), each triangle shaded by
/// how squarely it faces the camera at `eye`; returns how many props triangles were drawn.
fn draw_mesh(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    eye: Vec3,
    shown: &Shown,
    frame: usize,
    props: Option<&Mesh>,
) -> usize {
    let mut parts: Vec<(Cow<'_, [Vec3]>, &Mesh, Color32)> = Vec::new();
    if let Some(mesh) = shown.mesh.as_ref().filter(|_| shown.mesh_fits && shown.poses.frame_count() > 0) {
        let (positions, rest) = mesh.positions(&shown.poses, frame);
        parts.push((positions, rest, SKIN));
    }
    if let Some(props) = props {
        parts.push((Cow::Borrowed(&props.positions), props, PROP));
    }
    let drawn = draw_triangles(painter, project, eye, &parts);
    if props.is_some() { drawn.last().copied().unwrap_or(0) } else { 0 }
}

/// Fills the triangles of each part (positions in metres, the mesh whose triangles index
/// them, a colour) in one far-to-near order, each shaded by how squarely it faces the
/// camera at `eye`; returns per part how many were in front of the camera.
fn draw_triangles(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    eye: Vec3,
    parts: &[(Cow<'_, [Vec3]>, &Mesh, Color32)],
) -> Vec<usize> {
    let screens: Vec<Vec<Option<Pos2>>> =
        parts.iter().map(|(positions, _, _)| positions.iter().map(|p| project(*p)).collect()).collect();
    let mut faces: Vec<(f32, usize, [usize; 3], f32)> = Vec::new();
    for (part, ((positions, mesh, _), screen)) in parts.iter().zip(&screens).enumerate() {
        faces.extend(mesh.triangles.iter().filter_map(|t| {
            let [a, b, c] = t.map(|i| i as usize);
            let (pa, pb, pc) = (*positions.get(a)?, *positions.get(b)?, *positions.get(c)?);
            screen[a].and(screen[b]).and(screen[c])?;
            let centre = (pa + pb + pc) / 3.0;
            let facing = (pb - pa).cross(pc - pa).normalize_or_zero().dot((eye - centre).normalize_or_zero()).abs();
            Some((centre.distance_squared(eye), part, [a, b, c], facing))
        }));
    }
    faces.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut drawn = vec![0; parts.len()];
    let mut out = egui::epaint::Mesh::default();
    for &(_, part, corners, facing) in &faces {
        drawn[part] += 1;
        let colour = parts[part].2;
        let light = 0.35 + 0.65 * facing;
        let shade = |c: u8| (f32::from(c) * light) as u8;
        let base = out.vertices.len() as u32;
        for v in corners {
            out.colored_vertex(
                screens[part][v].unwrap_or_default(),
                Color32::from_rgb(shade(colour.r()), shade(colour.g()), shade(colour.b())),
            );
        }
        out.add_triangle(base, base + 1, base + 2);
    }
    painter.add(egui::Shape::mesh(out));
    drawn
}

/// The smoke's marker particles at `frame` as small squares, grey where the smoke is thin
/// and white where it is densest in this frame; returns how many were drawn (in front of
/// the camera).
fn draw_smoke(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    volumes: &VolumeSequence,
    frame: usize,
) -> usize {
    let Some(frame) = volumes.frames.get(frame) else { return 0 };
    let densest = frame.density.iter().copied().fold(0.0_f32, f32::max);
    let mut out = egui::epaint::Mesh::default();
    for p in &frame.particles_m {
        let Some(at) = project(Vec3::from(*p)) else { continue };
        let density = volumes.grid.index_at(Vec3::from(*p)).and_then(|n| frame.density.get(n)).copied();
        // Thin (or unsampled) smoke is dim grey, the frame's densest voxel white.
        let share = if densest > 0.0 { density.unwrap_or(0.0).clamp(0.0, densest) / densest } else { 0.0 };
        let colour = Color32::from_gray((110.0 + 145.0 * share) as u8).gamma_multiply(0.5 + 0.5 * share);
        out.add_colored_rect(Rect::from_center_size(at, Vec2::splat(2.0 * PARTICLE_HALF)), colour);
    }
    let drawn = out.vertices.len() / 4;
    painter.add(egui::Shape::mesh(out));
    drawn
}

/// A free body in the smoke as a wireframe: a ball as its three great circles, a cube as
/// its twelve edges, turned as the body is; returns where its centre is on screen.
fn draw_body(painter: &egui::Painter, project: &impl Fn(Vec3) -> Option<Pos2>, body: &BodyPose) -> Option<Pos2> {
    let centre = Vec3::from(body.centre_m);
    let rotation = glam::Quat::from_array(body.rotation_xyzw);
    let world = |local: Vec3| centre + rotation * local;
    let stroke = Stroke::new(1.5, BODY);
    let line = |points: &[Vec3]| {
        let points: Option<Vec<Pos2>> = points.iter().map(|p| project(world(*p))).collect();
        if let Some(points) = points {
            painter.add(egui::Shape::line(points, stroke));
        }
    };
    match body.shape {
        BodyShape::Ball { radius_m } => {
            const SEGMENTS: usize = 32;
            for (u, v) in [(Vec3::X, Vec3::Y), (Vec3::Y, Vec3::Z), (Vec3::Z, Vec3::X)] {
                let circle: Vec<Vec3> = (0..=SEGMENTS)
                    .map(|i| {
                        let a = i as f32 / SEGMENTS as f32 * std::f32::consts::TAU;
                        (u * a.cos() + v * a.sin()) * radius_m
                    })
                    .collect();
                line(&circle);
            }
        }
        BodyShape::Cube { edge_m } => {
            let h = 0.5 * edge_m;
            let corner = |i: usize| {
                Vec3::new(
                    if i & 1 == 0 { -h } else { h },
                    if i & 2 == 0 { -h } else { h },
                    if i & 4 == 0 { -h } else { h },
                )
            };
            // Corners differing in one bit share an edge.
            for i in 0..8 {
                for bit in [1, 2, 4] {
                    if i & bit == 0 {
                        line(&[corner(i), corner(i | bit)]);
                    }
                }
            }
        }
    }
    project(centre)
}

/// Bones as lines from each joint to its parent, joints as dots; a foot in contact at
/// `frame` gets a green disc on the floor under it.
fn draw_skeleton(
    painter: &egui::Painter,
    project: &impl Fn(Vec3) -> Option<Pos2>,
    shown: &Shown,
    frame: usize,
    colour: Color32,
    contacts: bool,
) {
    if shown.poses.frame_count() == 0 {
        return;
    }
    let pose = shown.poses.frame(frame);
    for (j, joint) in shown.clip.skeleton().joints().iter().enumerate() {
        let Some(here) = project(pose[j].translation) else { continue };
        if let Some(parent) = joint.parent
            && let Some(there) = project(pose[parent].translation)
        {
            painter.line_segment([there, here], Stroke::new(2.0, colour));
        }
        painter.circle_filled(here, 2.5, if colour == BONE { JOINT } else { colour });
    }
    if contacts {
        for (i, &foot) in shown.feet.iter().enumerate() {
            if shown.in_contact(i, frame)
                && let Some(p) = project(pose[foot].translation)
            {
                painter.circle_stroke(p, 7.0, Stroke::new(2.0, CONTACT));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect() -> Rect {
        Rect::from_min_size(Pos2::ZERO, Vec2::new(800.0, 400.0))
    }

    #[test]
    fn the_target_projects_to_the_centre_and_the_camera_right_goes_right() {
        let camera = Camera { yaw: 0.0, pitch: 0.0, distance: 4.0, target: Vec3::new(1.0, 1.0, 0.0) };
        let project = camera.projector(rect());
        let centre = project(camera.target).unwrap();
        assert!((centre - rect().center()).length() < 1e-3, "{centre:?}");
        // Yaw 0 puts the eye on +Z looking along −Z: world +X is screen right, +Y is up.
        let right = project(camera.target + Vec3::X * 0.5).unwrap();
        let up = project(camera.target + Vec3::Y * 0.5).unwrap();
        assert!(right.x > centre.x + 1.0 && (right.y - centre.y).abs() < 1e-3);
        assert!(up.y < centre.y - 1.0 && (up.x - centre.x).abs() < 1e-3);
        // Half a metre at 4 m with a 0.8 rad field of view over 400 points (pinhole model).
        let expected = 0.5 / 4.0 / (FOV_Y * 0.5).tan() * 200.0;
        assert!((up.y - centre.y + expected).abs() < 1e-2, "{} vs {expected}", centre.y - up.y);
        assert!(project(camera.eye() + Vec3::Z).is_none(), "behind the camera");
    }

    #[test]
    fn orbiting_keeps_the_distance_and_clamps_the_pitch() {
        let mut camera = Camera::default();
        camera.orbit(Vec2::new(300.0, -10_000.0));
        assert!((camera.eye().distance(camera.target) - camera.distance).abs() < 1e-4);
        assert_eq!(camera.pitch, -Camera::MAX_PITCH);
        camera.zoom(1e6);
        assert!(camera.distance >= 0.05 && camera.distance.is_finite());
    }

    #[test]
    fn framing_puts_every_corner_of_the_box_in_view() {
        let (lo, hi) = (Vec3::new(-3.0, 0.0, -1.0), Vec3::new(2.0, 1.8, 4.0));
        for (yaw, pitch) in [(0.0, 0.0), (1.0, 0.4), (-2.5, 1.4)] {
            let mut camera = Camera { yaw, pitch, ..Camera::default() };
            camera.frame(lo, hi, 2.0);
            let project = camera.projector(rect());
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let p = project(corner).unwrap();
                assert!(rect().expand(1.0).contains(p), "yaw {yaw}: {corner} at {p:?}");
            }
        }
    }

    #[test]
    fn panning_moves_the_target_in_the_view_plane() {
        let mut camera = Camera { yaw: 0.0, pitch: 0.0, distance: 4.0, target: Vec3::ZERO };
        camera.pan(Vec2::new(-100.0, 0.0), 400.0);
        assert!(camera.target.x > 0.0 && camera.target.y.abs() < 1e-6 && camera.target.z.abs() < 1e-6);
    }
}
