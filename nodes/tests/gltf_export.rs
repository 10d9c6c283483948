//! GLB export checked by the Khronos glTF Validator (0 errors, see `gltf_validator`), for a
//! synthetic clip with a skinned box and for every glTF sample of the corpus re-exported.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed unwrap is a failed test

mod gltf_validator;
mod node_eval;

use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec3};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file, write_glb, write_glb_file};
use kinegraph_nodes::model::{Clip, ImportScale, Joint, Mesh, Skeleton, Skin, forward_kinematics};

/// A three-joint chain (with an end site) bending over 20 frames, and a 1 × 2 × 1 m box
/// skinned to it: lower half to the hip, upper half blended between spine and chest.
fn synthetic() -> (Clip, Mesh) {
    let mut end = Joint::new("head_end", Some(2), Vec3::new(0.0, 0.3, 0.0));
    end.end_site = true;
    let skeleton = Arc::new(
        Skeleton::new(vec![
            Joint::new("hips", None, Vec3::new(0.0, 1.0, 0.0)),
            Joint::new("spine", Some(0), Vec3::new(0.0, 0.5, 0.0)),
            Joint::new("chest", Some(1), Vec3::new(0.0, 0.5, 0.0)),
            end,
        ])
        .unwrap(),
    );
    let frames = 20;
    let mut rotations = Vec::new();
    let mut translations = Vec::new();
    for f in 0..frames {
        let a = f as f32 * 0.05;
        rotations.extend([
            Quat::from_rotation_y(a),
            Quat::from_rotation_x(a),
            Quat::from_rotation_z(-a),
            Quat::IDENTITY,
        ]);
        translations.extend([
            Vec3::new(0.02 * f as f32, 1.0, 0.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 0.3, 0.0),
        ]);
    }
    let clip = Clip::new(skeleton.clone(), 30.0, rotations, translations, ImportScale::METRES).unwrap();

    let mut positions = Vec::new();
    for i in 0..8 {
        positions.push(Vec3::new(
            if i & 1 == 0 { -0.5 } else { 0.5 },
            if i & 2 == 0 { 0.5 } else { 2.5 },
            if i & 4 == 0 { -0.5 } else { 0.5 },
        ));
    }
    let triangles = vec![
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ];
    let normals = Mesh::compute_normals(&positions, &triangles);
    let joints = positions.iter().map(|p| if p.y < 1.0 { [0, 0, 0, 0] } else { [1, 2, 0, 0] }).collect();
    let weights =
        positions.iter().map(|p| if p.y < 1.0 { [1.0, 0.0, 0.0, 0.0] } else { [0.3, 0.7, 0.0, 0.0] }).collect();
    let rest = Clip::rest_pose(skeleton.clone(), 30.0, 1).unwrap();
    let inverse_bind_matrices =
        forward_kinematics(&rest).frame(0).iter().map(|t| t.to_mat4().inverse()).collect::<Vec<Mat4>>();
    let uvs = Some(positions.iter().map(|p| glam::Vec2::new(p.x + 0.5, p.z + 0.5)).collect());
    let mesh = Mesh {
        name: "box".into(),
        positions,
        normals,
        uvs,
        triangles,
        skin: Some(Skin { skeleton, joints, weights, inverse_bind_matrices }),
        ..Mesh::default()
    };
    (clip, mesh)
}

#[test]
fn synthetic_skinned_box_passes_the_validator_and_reads_back() {
    let (clip, mesh) = synthetic();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.glb");
    let warnings = write_glb_file(&path, &clip, Some(&mesh)).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let bare = dir.path().join("bare.glb");
    write_glb_file(&bare, &clip, None).unwrap();
    gltf_validator::validate_gltf(&[path.clone(), bare]);

    let options = GltfReadOptions { sample_fps: Some(30.0), ..Default::default() };
    let back = read_gltf_file(&path, &options).unwrap().value;
    let c2 = &back.clips[0].clip;
    assert_eq!(c2.frame_count(), 20);
    let (p1, p2) = (forward_kinematics(&clip), forward_kinematics(c2));
    for f in 0..20 {
        for j in 0..4 {
            assert!((p1.position(f, j) - p2.position(f, j)).length() < 1e-5, "frame {f} joint {j}");
        }
    }
    let m2 = &back.meshes[0];
    assert_eq!(m2.triangles, mesh.triangles);
    let s2 = m2.skin.as_ref().unwrap();
    assert_eq!(s2.joints, mesh.skin.as_ref().unwrap().joints);
    for (a, b) in m2.positions.iter().zip(&mesh.positions) {
        assert!((*a - *b).length() < 1e-5);
    }
}

/// Issue 16: a scene's props (the stool a simulated character sits on) go into the file
/// beside the skinned mesh as their own unskinned object where they stand. Read back with
/// the `gltf` crate: a root node "stool" with no skin whose box spans what the chair's
/// numbers give by hand (0.5 m wide, from the ground to the 0.45 m seat, its front edge
/// 0.15 m behind the origin, 0.45 m deep, for a figure facing +Z), every face pointing
/// out of the box; the character keeps its skin; the validator passes.
#[test]
fn props_are_written_where_they_stand_beside_the_skinned_mesh() {
    use kinegraph_nodes::formats::gltf::{GlbAnimation, build_glb_animations};
    use kinegraph_nodes::kernels::physics::seat::Chair;
    let (clip, mesh) = synthetic();
    let stool = Chair::default().place(glam::Vec2::ZERO, Vec3::Z).mesh();
    let animations = [GlbAnimation { name: "clip", clip: &clip }];
    let built = build_glb_animations(&animations, Some(&mesh), Some(&stool)).unwrap();
    assert!(built.warnings.is_empty(), "{:?}", built.warnings);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("with_stool.glb");
    std::fs::write(&path, built.value.into_bytes()).unwrap();
    gltf_validator::validate_gltf(std::slice::from_ref(&path));

    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let scene = doc.default_scene().unwrap();
    let node = scene.nodes().find(|n| n.name() == Some("stool")).expect("a root node named stool");
    assert!(node.skin().is_none());
    assert_eq!(Mat4::from_cols_array_2d(&node.transform().matrix()), Mat4::IDENTITY);
    let primitive = node.mesh().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let positions: Vec<Vec3> = reader.read_positions().unwrap().map(Vec3::from).collect();
    let normals: Vec<Vec3> = reader.read_normals().unwrap().map(Vec3::from).collect();
    let lo = positions.iter().copied().fold(Vec3::INFINITY, Vec3::min);
    let hi = positions.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
    assert!(lo.distance(Vec3::new(-0.25, 0.0, -0.6)) < 1e-6, "{lo}");
    assert!(hi.distance(Vec3::new(0.25, 0.45, -0.15)) < 1e-6, "{hi}");
    let centre = 0.5 * (lo + hi);
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(indices.len(), 36);
    for t in indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let outward = ((a + b + c) / 3.0 - centre).normalize_or_zero();
        assert!((b - a).cross(c - a).normalize_or_zero().dot(outward) > 0.4, "winding of {t:?}");
        assert!(normals[t[0] as usize].dot(outward) > 0.4, "normal of {t:?}");
    }
    let skinned = doc.nodes().filter(|n| n.skin().is_some() && n.mesh().is_some()).count();
    assert_eq!(skinned, 1, "the character keeps its skin");
}

#[test]
fn empty_clip_writes_a_valid_file_without_animation() {
    let (clip, _) = synthetic();
    let empty = clip.slice(0, 0);
    let glb = write_glb(&empty, None).unwrap();
    assert!(glb.warnings.iter().any(|w| w.contains("no frames")));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.glb");
    std::fs::write(&path, &glb.value).unwrap();
    gltf_validator::validate_gltf(&[path]);
}

#[test]
fn mesh_on_another_skeleton_is_refused() {
    let (clip, mut mesh) = synthetic();
    let other = Arc::new(Skeleton::new(vec![Joint::new("x", None, Vec3::ZERO)]).unwrap());
    if let Some(skin) = &mut mesh.skin {
        skin.skeleton = other;
    }
    let err = write_glb_file(Path::new("/tmp/never-written.glb"), &clip, Some(&mesh)).unwrap_err();
    assert!(err.to_string().contains("never-written.glb") && err.message.contains("different skeleton"), "{err}");
}

#[test]
fn corpus_samples_re_exported_pass_the_validator() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for name in ["CesiumMan.glb", "Fox.glb", "RiggedSimple.glb", "SimpleSkin.gltf"] {
        let asset = read_gltf_file(&data.join("gltf").join(name), &GltfReadOptions::default()).unwrap().value;
        for (k, clip) in asset.clips.iter().enumerate() {
            let path = dir.path().join(format!("{name}.{k}.glb"));
            write_glb_file(&path, &clip.clip, asset.meshes.first()).unwrap();
            files.push(path);
        }
    }
    gltf_validator::validate_gltf(&files);
}

/// A CMU walk carried onto CesiumMan (another naming, rest pose and size) through the
/// automatic bone map, exported with CesiumMan's skinned mesh: the validator passes, and
/// the character keeps its feet near the floor it stands on.
#[test]
fn a_cmu_walk_on_cesium_man_passes_the_validator() {
    use kinegraph_nodes::builtin::ik::map::{Bodies, TransferOptions, map_by_roles, transfer};
    use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
    let Some(data) = shared_data() else { return };
    let walk = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value.0;
    let walk = walk.slice(1, walk.frame_count());
    let asset = read_gltf_file(&data.join("gltf/CesiumMan.glb"), &GltfReadOptions::default()).unwrap().value;
    let man = &asset.clips[0].clip;
    let bodies = Bodies::of(man, &walk).unwrap();
    let (t, s) = (&bodies.target, &bodies.source);
    let map = map_by_roles(man.skeleton(), t, walk.skeleton(), s);
    let out = transfer(&walk, man, &map, &TransferOptions { bodies: Some(&bodies), ..Default::default() }).unwrap();
    println!("CesiumMan: {} pairs, unmapped {:?}, root scale {:.3}", map.joints.len(), out.unmapped, out.root_scale);
    assert!(out.clip.rotations().iter().all(|q| q.is_finite()));
    // Lowest point of the feet over the walk against the CesiumMan's own first frame.
    let lowest = |c: &Clip| {
        let poses = forward_kinematics(c);
        (0..c.frame_count())
            .flat_map(|f| t.legs.iter().map(move |l| (f, l.joints()[2])))
            .map(|(f, j)| poses.position(f, j).y)
            .fold(f32::INFINITY, f32::min)
    };
    let (own, carried) = (lowest(man), lowest(&out.clip));
    println!("ankle floor: CesiumMan's own walk {own:.3} m, carried CMU walk {carried:.3} m");
    assert!((own - carried).abs() < 0.05, "{own} vs {carried}");
    // CesiumMan's only joints below the ankles are heels: by them alone its front would be
    // its back and its sides swapped. Independently of the roles: over its own walk, the
    // knees sit behind the hip–ankle line as seen from the heels, ahead as seen on CMU's toes.
    let knees_ahead = |clip: &Clip, roles: &kinegraph_nodes::kernels::roles::BodyRoles| {
        let poses = forward_kinematics(clip);
        let tip = |l: usize| *roles.legs[l].chain.last().unwrap();
        let toward_tip: Vec3 = (0..2)
            .map(|l| (poses.position(0, tip(l)) - poses.position(0, roles.legs[l].joints()[2])).with_y(0.0))
            .sum::<Vec3>()
            .normalize_or_zero();
        let mut ahead = 0.0;
        for f in 0..clip.frame_count() {
            for leg in &roles.legs {
                let [hip, knee, ankle] = leg.joints().map(|j| poses.position(f, j));
                ahead += (knee - 0.5 * (hip + ankle)).dot(toward_tip) / (2 * clip.frame_count()) as f32;
            }
        }
        ahead
    };
    let (man_ahead, cmu_ahead) = (knees_ahead(man, t), knees_ahead(&walk, s));
    println!(
        "knees ahead of the hip–ankle line toward the leaf below the ankle: CesiumMan {man_ahead:.3} m, CMU {cmu_ahead:.3} m"
    );
    assert!(man_ahead < 0.0 && cmu_ahead > 0.0);
    assert!(map.joints["leg_joint_L_1"] == "LeftUpLeg" && map.joints["Skeleton_arm_joint_R"] == "RightArm", "{map:?}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cmu_on_cesium_man.glb");
    write_glb_file(&path, &out.clip, asset.meshes.first()).unwrap();
    gltf_validator::validate_gltf(&[path]);
}

/// The inverse bind matrices of every skin in a GLB, read back by the `gltf` crate.
fn inverse_bind_matrices(path: &Path) -> Vec<[[f32; 4]; 4]> {
    let (doc, buffers, _) = gltf::import(path).unwrap();
    doc.skins()
        .flat_map(|skin| {
            let reader = skin.reader(|b| Some(&buffers[b.index()]));
            reader.read_inverse_bind_matrices().map(|m| m.collect::<Vec<_>>()).unwrap_or_default()
        })
        .collect()
}

/// Issue 18: a skeleton exported without a mesh gets inverse bind matrices the exporter
/// computes; each must be exactly affine (last row exactly 0, 0, 0, 1, which the validator
/// checks as ACCESSOR_INVALID_IBM) and still invert the joint's rest world transform.
/// Checked on every rig of the corpus, the Mixamo Xbot included (rest rotations on every joint).
#[test]
fn computed_inverse_bind_matrices_are_exactly_affine_on_every_corpus_rig() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for name in ["Xbot.glb", "CesiumMan.glb", "Fox.glb", "RiggedSimple.glb", "SimpleSkin.gltf"] {
        let asset = read_gltf_file(&data.join("gltf").join(name), &GltfReadOptions::default()).unwrap().value;
        let clip = &asset.clips[0].clip;
        let path = dir.path().join(format!("{name}.skeleton.glb"));
        write_glb_file(&path, clip, None).unwrap();
        let ibms = inverse_bind_matrices(&path);
        assert_eq!(ibms.len(), clip.joint_count(), "{name}");
        // The rest world transforms by the reader's own FK of a one-frame rest clip.
        let rest = Clip::rest_pose(clip.skeleton().clone(), 30.0, 1).unwrap();
        let world = forward_kinematics(&rest);
        for (j, m) in ibms.iter().enumerate() {
            assert_eq!([m[0][3], m[1][3], m[2][3], m[3][3]], [0.0, 0.0, 0.0, 1.0], "{name} joint {j}");
            let product = Mat4::from_cols_array_2d(m) * world.frame(0)[j].to_mat4();
            assert!(product.abs_diff_eq(Mat4::IDENTITY, 1e-4), "{name} joint {j}: {product}");
        }
        files.push(path);
    }
    gltf_validator::validate_gltf(&files);
}

/// Issue 18: a mesh without a skin written beside an animated skeleton is reported, not
/// silently written standing still.
#[test]
fn an_unskinned_mesh_beside_an_animated_skeleton_is_warned_about() {
    let (clip, mut mesh) = synthetic();
    mesh.skin = None;
    let glb = write_glb(&clip, Some(&mesh)).unwrap();
    assert!(glb.warnings.iter().any(|w| w.contains("'box' has no skin")), "{:?}", glb.warnings);
    // Still, nothing to warn about for a skinned mesh.
    let (clip, mesh) = synthetic();
    assert!(write_glb(&clip, Some(&mesh)).unwrap().warnings.is_empty());
}

/// Issue 18, `character.load` → `export.glb` round trip on the corpus characters: the
/// Mixamo Xbot's two skinned meshes (Beta_Joints, Beta_Surface) and CesiumMan come back from
/// the exported GLB as the same meshes (names, vertex counts), with the same rest-pose vertex positions (< 1e-5 m) as the reader gives
/// for the original file's meshes, the same skin weights on the same joints (by name), and
/// the validator reports 0 errors.
#[test]
fn whole_characters_round_trip_through_export() {
    use kinegraph_nodes::kernels::load::load_character;
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for name in ["Xbot.glb", "CesiumMan.glb"] {
        let path = data.join("gltf").join(name);
        let original = read_gltf_file(&path, &GltfReadOptions::default()).unwrap().value;
        let character = load_character(&path, 0).unwrap().value;
        assert_eq!(character.parts.len(), original.meshes.len(), "{name}");
        assert!(character.parts.iter().all(|p| p.binding == "skinned"), "{name}: {:?}", character.parts);
        let out = dir.path().join(format!("{name}.character.glb"));
        let warnings = write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
        println!(
            "{name}: {} meshes, {} vertices; export warnings {warnings:?}",
            character.parts.len(),
            character.mesh.positions.len()
        );
        let back = read_gltf_file(&out, &GltfReadOptions::default()).unwrap().value;
        // One mesh back per original mesh, by name, with its vertices in order: positions,
        // and weights per joint name.
        let names = |meshes: &[Mesh]| meshes.iter().map(|m| (m.name.clone(), m.positions.len())).collect::<Vec<_>>();
        assert_eq!(names(&back.meshes), names(&original.meshes), "{name}");
        let (mut worst_pos, mut worst_weight) = (0.0f32, 0.0f32);
        for (part, m) in original.meshes.iter().zip(&back.meshes) {
            let ps = part.skin.as_ref().unwrap();
            let skin = m.skin.as_ref().unwrap();
            for (v, p) in part.positions.iter().enumerate() {
                worst_pos = worst_pos.max(p.distance(m.positions[v]));
                let by_name = |sk: &Skeleton, joints: [u16; 4], weights: [f32; 4]| {
                    let mut w: std::collections::BTreeMap<String, f32> = Default::default();
                    for i in 0..4 {
                        if weights[i] > 0.0 {
                            *w.entry(sk.joints()[joints[i] as usize].name.clone()).or_default() += weights[i];
                        }
                    }
                    w
                };
                let (a, b) = (
                    by_name(&ps.skeleton, ps.joints[v], ps.weights[v]),
                    by_name(&skin.skeleton, skin.joints[v], skin.weights[v]),
                );
                assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "{name} vertex {v}");
                for (x, y) in a.values().zip(b.values()) {
                    worst_weight = worst_weight.max((x - y).abs());
                }
            }
        }
        println!(
            "{name}: worst rest-pose vertex distance {worst_pos:.2e} m, worst weight difference {worst_weight:.2e}"
        );
        assert!(worst_pos < 1e-5, "{name}: {worst_pos}");
        assert!(worst_weight < 1e-5, "{name}: {worst_weight}");
        files.push(out);
    }
    gltf_validator::validate_gltf(&files);
}

/// A two-joint glTF (root at y = 1, bone 1 m above it) with an unskinned triangle node
/// parented to the bone, 0.5 m along X: `character.load` binds it rigidly to the bone.
const PROP_ON_A_BONE: &str = r#"{
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [
    {"name": "root", "translation": [0, 1, 0], "children": [1]},
    {"name": "bone", "translation": [0, 1, 0], "children": [2]},
    {"name": "prop", "translation": [0.5, 0, 0], "mesh": 0}
  ],
  "skins": [{"joints": [0, 1]}],
  "meshes": [{"name": "plate", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
  ]
}"#;

#[test]
fn a_mesh_parented_to_a_bone_moves_rigidly_with_it() {
    use kinegraph_nodes::kernels::load::load_character;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("prop.gltf");
    std::fs::write(&path, PROP_ON_A_BONE).unwrap();
    let loaded = load_character(&path, 0).unwrap();
    let c = loaded.value;
    assert_eq!(c.parts[0].binding, "rigid to bone");
    let skin = c.mesh.skin.as_ref().unwrap();
    // Hand-solved rest world positions: root (0,1,0) + bone (0,1,0) + prop (0.5,0,0).
    let want = [Vec3::new(0.5, 2.0, 0.0), Vec3::new(1.5, 2.0, 0.0), Vec3::new(0.5, 3.0, 0.0)];
    for (p, w) in c.mesh.positions.iter().zip(want) {
        assert!(p.distance(w) < 1e-6, "{p} vs {w}");
    }
    assert!(skin.joints.iter().all(|j| j[0] == 1) && skin.weights.iter().all(|w| w[0] == 1.0));
    // Turning the bone 90° about Z swings the plate about the bone's origin (0, 2, 0):
    // (0.5, 2, 0) → (0, 2.5, 0), by the skinning matrix world × inverse bind.
    let turned = kinegraph_nodes::model::fk::Transform {
        rotation: Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
        translation: Vec3::new(0.0, 2.0, 0.0),
    };
    let moved = (turned.to_mat4() * skin.inverse_bind_matrices[1]).transform_point3(c.mesh.positions[0]);
    assert!(moved.distance(Vec3::new(0.0, 2.5, 0.0)) < 1e-6, "{moved}");
    let out = dir.path().join("prop.glb");
    write_glb_file(&out, &c.clip, Some(&c.mesh)).unwrap();
    gltf_validator::validate_gltf(&[out]);
}

/// Issue 18: Fox's three animations (Survey, Walk, Run) written into one GLB beside its
/// mesh. Read back with the `gltf` crate: three animations with the given names, keys at
/// frame / fps for each clip's frame count, and at every fifth key the joints placed by
/// the file's own node hierarchy (rest TRS replaced by the channels' values) where FK of
/// the source clip puts them.
#[test]
fn several_named_animations_go_into_one_file() {
    use kinegraph_nodes::formats::gltf::{GlbAnimation, build_glb_animations};
    let Some(data) = shared_data() else { return };
    let asset = read_gltf_file(&data.join("gltf/Fox.glb"), &GltfReadOptions::default()).unwrap().value;
    assert_eq!(asset.clips.len(), 3);
    let animations: Vec<GlbAnimation<'_>> =
        asset.clips.iter().map(|c| GlbAnimation { name: &c.name, clip: &c.clip }).collect();
    let built = build_glb_animations(&animations, asset.meshes.first(), None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fox_three.glb");
    std::fs::write(&path, built.value.into_bytes()).unwrap();
    gltf_validator::validate_gltf(std::slice::from_ref(&path));

    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let names: Vec<&str> = doc.animations().map(|a| a.name().unwrap()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    let rest: Vec<Mat4> = doc.nodes().map(|n| Mat4::from_cols_array_2d(&n.transform().matrix())).collect();
    let mut checked = 0;
    for (animation, source) in doc.animations().zip(&asset.clips) {
        let clip = &source.clip;
        let frames = clip.frame_count();
        // Each channel's keys, and the joint node it drives.
        let mut rotations = vec![None; rest.len()];
        let mut translations = vec![None; rest.len()];
        for channel in animation.channels() {
            let r = channel.reader(|b| Some(&buffers[b.index()]));
            let times: Vec<f32> = r.read_inputs().unwrap().collect();
            assert_eq!(times.len(), frames, "{}", source.name);
            assert!((times[frames - 1] as f64 - (frames - 1) as f64 / clip.fps()).abs() < 1e-5);
            let node = channel.target().node().index();
            match r.read_outputs().unwrap() {
                gltf::animation::util::ReadOutputs::Rotations(q) => {
                    rotations[node] = Some(q.into_f32().map(Quat::from_array).collect::<Vec<_>>())
                }
                gltf::animation::util::ReadOutputs::Translations(t) => {
                    translations[node] = Some(t.map(Vec3::from).collect::<Vec<_>>())
                }
                _ => panic!("only rotations and translations are written"),
            }
        }
        assert_eq!(rotations.iter().flatten().count(), clip.joint_count(), "{}", source.name);
        let poses = forward_kinematics(clip);
        for f in (0..frames).step_by(5) {
            let local: Vec<Mat4> = (0..rest.len())
                .map(|n| {
                    let (s, r, t) = rest[n].to_scale_rotation_translation();
                    let r = rotations[n].as_ref().map_or(r, |q| q[f]);
                    let t = translations[n].as_ref().map_or(t, |v| v[f]);
                    Mat4::from_scale_rotation_translation(s, r, t)
                })
                .collect();
            let world = gltf_validator::node_worlds(&doc, &local);
            for (j, (joint, node)) in clip.skeleton().joints().iter().zip(doc.nodes()).enumerate() {
                // Node j is joint j (the writer's layout, checked by name).
                assert_eq!(node.name(), Some(joint.name.as_str()));
                let want = poses.position(f, j);
                let got = world[j].w_axis.truncate();
                // Fox is ~100 units across: f32 resolution there is ~1e-5 per unit.
                assert!(got.distance(want) < 1e-5 * want.length().max(1.0), "{} frame {f} joint {j}", source.name);
                checked += 1;
            }
        }
    }
    println!("three animations, {checked} joint positions checked against FK of the source clips");
}

/// `export.glb` with a second clip: the file holds both animations under the given names;
/// a name used twice is refused naming the parameter, a clip of another skeleton naming
/// the input; a skinned mesh connected as props is refused naming that input.
#[test]
fn export_glb_node_writes_extra_clips_and_refuses_clashes() {
    use kinegraph_nodes::node::{NodeError, ParamValue, Value};
    use node_eval::eval_node;
    let (clip, mesh) = synthetic();
    let second = clip.slice(5, 15);
    let dir = tempfile::tempdir().unwrap();
    let run = |name_2: &str, other: Clip, props: Option<Mesh>| -> Result<(), NodeError> {
        let params: Vec<(&str, ParamValue)> =
            [("file", "both.glb"), ("name", "bend"), ("name_2", name_2), ("name_3", "clip_3"), ("name_4", "clip_4")]
                .into_iter()
                .map(|(k, v)| (k, ParamValue::Text(v.to_owned())))
                .collect();
        let inputs = vec![
            Some(Value::Clip(Arc::new(clip.clone()))),
            Some(Value::Mesh(Arc::new(mesh.clone()))),
            Some(Value::Clip(Arc::new(other))),
            None,
            None,
            props.map(|p| Value::Mesh(Arc::new(p))),
        ];
        eval_node("export.glb", inputs, &params, dir.path()).map(drop)
    };
    run("bend_again", second.clone(), None).unwrap();
    let (doc, _, _) = gltf::import(dir.path().join("both.glb")).unwrap();
    let animations: Vec<(String, usize)> = doc
        .animations()
        .map(|a| (a.name().unwrap().to_owned(), a.samplers().next().unwrap().input().count()))
        .collect();
    assert_eq!(animations, [("bend".to_owned(), 20), ("bend_again".to_owned(), 10)]);
    let err = run("bend", second.clone(), None).unwrap_err();
    assert!(matches!(&err, NodeError::Param { param: "name_2", .. }), "{err}");
    let other = Arc::new(Skeleton::new(vec![Joint::new("x", None, Vec3::ZERO)]).unwrap());
    let err = run("other", Clip::rest_pose(other, 30.0, 2).unwrap(), None).unwrap_err();
    assert!(matches!(&err, NodeError::Input { port: "clip_2", .. }), "{err}");
    // Props stand still: a skinned mesh there is refused, naming the port.
    let err = run("bend_again", second, Some(mesh.clone())).unwrap_err();
    assert!(matches!(&err, NodeError::Input { port: "props", .. }), "{err}");
}

/// Issue 18: a character whose rest pose is its skin's bind pose keeps the file's own
/// inverse bind matrices. Fox (no scaled ancestor): exported bit for bit as the source
/// stores them. Xbot: its Armature's 0.01 scale is baked into the skeleton, so the file's
/// matrices come back with that scale taken out (rows x, y, z × 0.01). CesiumMan, whose
/// nodes' rest pose is not its bind pose: computed ones, exactly affine and inverting the
/// exported rest pose.
#[test]
fn file_inverse_bind_matrices_are_kept_when_they_fit() {
    use kinegraph_nodes::kernels::load::load_character;
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    for (name, scale, kept) in [("Fox.glb", 1.0f32, true), ("Xbot.glb", 0.01, true), ("CesiumMan.glb", 1.0, false)] {
        let source = data.join("gltf").join(name);
        let character = load_character(&source, 0).unwrap().value;
        assert_eq!(character.file_inverse_bind_matrices, kept, "{name}");
        let out = dir.path().join(format!("{name}.ibm.glb"));
        write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
        let (source_ibms, exported) = (inverse_bind_matrices(&source), inverse_bind_matrices(&out));
        assert_eq!(source_ibms.len(), exported.len(), "{name}");
        let mut worst = 0.0f32;
        for (j, (s, e)) in source_ibms.iter().zip(&exported).enumerate() {
            let s = Mat4::from_cols_array_2d(s);
            let e = Mat4::from_cols_array_2d(e);
            assert_eq!([e.x_axis.w, e.y_axis.w, e.z_axis.w, e.w_axis.w], [0.0, 0.0, 0.0, 1.0], "{name} joint {j}");
            let want = Mat4::from_scale(Vec3::splat(scale)) * s;
            // Relative to the entry's size: translations reach 1.6 m.
            for (a, b) in e.to_cols_array().into_iter().zip(want.to_cols_array()) {
                worst = worst.max((a - b).abs() / b.abs().max(1.0));
            }
        }
        println!(
            "{name}: kept {kept}, largest relative entry difference from the file's (scaled) matrices {worst:.2e}"
        );
        if !kept {
            assert!(worst > 0.1, "{name}: the file's matrices do not fit, yet the written ones equal them");
            let rest = Clip::rest_pose(character.clip.skeleton().clone(), 30.0, 1).unwrap();
            let world = forward_kinematics(&rest);
            for (j, e) in exported.iter().enumerate() {
                let product = Mat4::from_cols_array_2d(e) * world.frame(0)[j].to_mat4();
                assert!(product.abs_diff_eq(Mat4::IDENTITY, 1e-4), "{name} joint {j}: {product}");
            }
        } else if scale == 1.0 {
            assert_eq!(worst, 0.0, "{name}: not the file's own bits");
        } else {
            // The joints' own scales (Hips: 1, 1, 0.99999994) make the baked scale differ
            // from 0.01 by a few f32 steps along each chain.
            assert!(worst < 1e-5, "{name}: {worst}");
        }
    }
}

/// The synthetic box with its first six triangles (three faces) red and the other six
/// blue, sharing corner vertices across the two: written as two primitives,
/// each with its material and six triangles over its own eight corners (shared corners
/// written once per primitive), every triangle on the same positions as before. Without
/// UVs a textured material goes out untextured, with a warning.
#[test]
fn a_two_material_box_writes_one_primitive_per_material() {
    use kinegraph_nodes::model::{Image, Material, MaterialRange, Sampler, Texture};
    let (clip, mut mesh) = synthetic();
    let paint = |name: &str, rgba: [f32; 4]| Material {
        name: Some(name.into()),
        base_color_factor: rgba,
        metallic_factor: 0.0,
        ..Material::default()
    };
    mesh.materials = vec![paint("red", [1.0, 0.0, 0.0, 1.0]), paint("blue", [0.0, 0.0, 1.0, 1.0])];
    mesh.material_ranges = vec![
        MaterialRange { first_triangle: 0, triangle_count: 6, material: Some(0) },
        MaterialRange { first_triangle: 6, triangle_count: 6, material: Some(1) },
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two_materials.glb");
    assert!(write_glb_file(&path, &clip, Some(&mesh)).unwrap().is_empty());
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let prims: Vec<gltf::Primitive<'_>> = doc.meshes().flat_map(|m| m.primitives()).collect();
    assert_eq!(prims.len(), 2);
    for (k, prim) in prims.iter().enumerate() {
        let m = prim.material();
        assert_eq!(m.name(), mesh.materials[k].name.as_deref());
        assert_eq!(m.pbr_metallic_roughness().base_color_factor(), mesh.materials[k].base_color_factor);
        let r = prim.reader(|b| Some(&buffers[b.index()]));
        let positions: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
        let indices: Vec<u32> = r.read_indices().unwrap().into_u32().collect();
        assert_eq!(positions.len(), 8, "every corner of the box is used by both halves");
        let source = &mesh.triangles[6 * k..6 * k + 6];
        for (t, want) in indices.chunks_exact(3).zip(source) {
            for c in 0..3 {
                assert_eq!(positions[t[c] as usize], mesh.positions[want[c] as usize]);
            }
        }
    }
    gltf_validator::validate_gltf(std::slice::from_ref(&path));

    // A texture on a mesh without UVs.
    let image = Arc::new(Image { name: None, mime_type: "image/png".into(), bytes: b"\x89PNG\r\n\x1a\n".to_vec() });
    mesh.materials[0].base_color_texture = Some(Texture { image, sampler: Sampler::default() });
    mesh.uvs = None;
    let warnings = write_glb_file(&path, &clip, Some(&mesh)).unwrap();
    assert!(warnings.iter().any(|w| w.contains("no UVs")), "{warnings:?}");
    let (doc, _, images) = gltf::import(&path).unwrap();
    assert_eq!((doc.textures().count(), images.len()), (0, 0));
    gltf_validator::validate_gltf(&[path]);
}

/// Two synthetic boxes merged as the parts "left" and "right" (8 vertices and 12
/// triangles each), red over the left box and the right box's first six triangles (one
/// material run across the parts' boundary), blue over the rest, "left" held by an object
/// named "left box": written as two glTF meshes named after the parts, on two nodes named
/// after their objects ("left box", and "right" for the part without one), bound to the
/// same skin, "left" one red
/// primitive of 12 triangles, "right" a red and a blue one of 6, every triangle on the
/// positions it had. A part whose triangle reaches into another part is refused by name.
#[test]
fn parts_are_written_as_separate_meshes_sharing_the_skin() {
    use kinegraph_nodes::model::{Material, MaterialRange};
    let (clip, mut mesh) = synthetic();
    let box_triangles = mesh.triangles.clone();
    mesh.push_part("left", Some("left box"));
    let skin = mesh.skin.as_mut().unwrap();
    skin.joints.extend_from_within(..);
    skin.weights.extend_from_within(..);
    mesh.positions.extend(mesh.positions.clone().iter().map(|p| *p + Vec3::X * 2.0));
    mesh.normals.extend_from_within(..);
    mesh.uvs.as_mut().unwrap().extend_from_within(..);
    mesh.triangles.extend(box_triangles.iter().map(|t| t.map(|i| i + 8)));
    mesh.push_part("right", None);
    let paint = |name: &str| Material { name: Some(name.into()), ..Material::default() };
    mesh.materials = vec![paint("red"), paint("blue")];
    mesh.material_ranges = vec![
        MaterialRange { first_triangle: 0, triangle_count: 18, material: Some(0) },
        MaterialRange { first_triangle: 18, triangle_count: 6, material: Some(1) },
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("parts.glb");
    assert!(write_glb_file(&path, &clip, Some(&mesh)).unwrap().is_empty());
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let nodes: Vec<gltf::Node<'_>> = doc.nodes().filter(|n| n.mesh().is_some()).collect();
    let names: Vec<_> = nodes.iter().map(|n| (n.name().unwrap(), n.mesh().unwrap().name().unwrap())).collect();
    assert_eq!(names, vec![("left box", "left"), ("right", "right")]);
    assert_eq!(nodes.iter().map(|n| n.skin().unwrap().index()).collect::<Vec<_>>(), vec![0, 0]);
    let mut drawn = Vec::new();
    for (k, node) in nodes.iter().enumerate() {
        for prim in node.mesh().unwrap().primitives() {
            let r = prim.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
            let indices: Vec<u32> = r.read_indices().unwrap().into_u32().collect();
            assert_eq!(positions.len(), 8, "part {k}: its own box's corners only");
            drawn.push((k, prim.material().name().unwrap().to_owned(), indices.len() / 3));
            let first = if k == 0 {
                0
            } else if drawn.last().unwrap().1 == "red" {
                12
            } else {
                18
            };
            for (t, want) in indices.chunks_exact(3).zip(&mesh.triangles[first..]) {
                for c in 0..3 {
                    assert_eq!(positions[t[c] as usize], mesh.positions[want[c] as usize]);
                }
            }
        }
    }
    assert_eq!(drawn, vec![(0, "red".into(), 12), (1, "red".into(), 6), (1, "blue".into(), 6)]);
    gltf_validator::validate_gltf(std::slice::from_ref(&path));

    mesh.triangles[12][0] = 7;
    let err = write_glb(&clip, Some(&mesh)).unwrap_err().to_string();
    assert!(err.contains("mesh 'box': part 'right' triangle 12 uses a vertex outside its vertices 8..16"), "{err}");
}

/// A glTF of two skinned triangle meshes (`first` and `second`, on nodes 4 and 5, skins 0
/// and 1, every vertex on its skin's first joint) over the joint nodes 0-3, 6 described by
/// `nodes` (JSON objects, in order), with the scene's root nodes `roots` and the two skins'
/// joint lists `skins`.
fn two_skinned_meshes(nodes: [&str; 5], roots: &str, skins: [&str; 2]) -> String {
    use base64::Engine as _;
    // One triangle: positions (3 × VEC3 f32), indices (3 × u16, 2 bytes padding), joints
    // (3 × VEC4 u8), weights (3 × VEC4 f32).
    let mut bin = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.3, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin.extend_from_slice(&[0u8; 12]);
    for _ in 0..3 {
        for w in [1.0f32, 0.0, 0.0, 0.0] {
            bin.extend_from_slice(&w.to_le_bytes());
        }
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&bin);
    let primitive = r#"{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 1}"#;
    let [n0, n1, n2, n3, n6] = nodes;
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": {roots}}}],
  "nodes": [{n0}, {n1}, {n2}, {n3},
    {{"name": "first", "mesh": 0, "skin": 0}},
    {{"name": "second", "mesh": 1, "skin": 1}},
    {n6}],
  "skins": [{{"joints": {}}}, {{"joints": {}}}],
  "meshes": [{{"name": "first", "primitives": [{primitive}]}}, {{"name": "second", "primitives": [{primitive}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}},
                  {{"buffer": 0, "byteOffset": 44, "byteLength": 12}}, {{"buffer": 0, "byteOffset": 56, "byteLength": 48}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [0.2, 0.3, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}},
    {{"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"}},
    {{"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}}
  ]
}}"#,
        skins[0],
        skins[1],
        len = bin.len()
    )
}

/// Bad input, issue 18: a file holding two characters (two skins over two separate
/// armatures, a skinned mesh on each) is not one character. `character.load` refuses it
/// with a structure error naming the file, the mesh of the second skin and the joints it
/// binds outside the skeleton; reading the file as meshes alone still works (that mesh
/// unskinned, with a warning). Two armatures under one scene node are refused too (the
/// skin on bones under two roots), while one armature with a skin per mesh, the second
/// listing a bone the first does not (a jaw), is one character with both meshes skinned.
#[test]
fn two_meshes_with_conflicting_skins_are_refused_as_one_character() {
    use kinegraph_nodes::formats::FormatErrorKind;
    use kinegraph_nodes::kernels::load::load_character;
    let hero = [
        r#"{"name": "hero_root", "translation": [0, 1, 0], "children": [1]}"#,
        r#"{"name": "hero_spine", "translation": [0, 0.5, 0], "children": [6]}"#,
        r#"{"name": "sidekick_root", "translation": [2, 1, 0], "children": [3]}"#,
        r#"{"name": "sidekick_spine", "translation": [0, 0.4, 0]}"#,
        r#"{"name": "hero_jaw", "translation": [0, 0.2, 0.1]}"#,
    ];
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: String| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let path = write("two_characters.gltf", two_skinned_meshes(hero, "[0, 2, 4, 5]", ["[0, 1]", "[2, 3]"]));
    let error = load_character(&path, 0).map(|_| ()).unwrap_err();
    println!("{error}");
    assert_eq!((error.file.as_path(), error.kind), (path.as_path(), FormatErrorKind::Structure));
    for what in ["two skeletons", "'second'", "skin 1", "2 joints", "sidekick_root, sidekick_spine"] {
        assert!(error.message.contains(what), "{what}: {error}");
    }
    let asset = read_gltf_file(&path, &GltfReadOptions::default()).unwrap();
    assert_eq!(asset.value.meshes.len(), 2);
    assert!(asset.value.meshes[0].skin.is_some() && asset.value.meshes[1].skin.is_none());
    assert!(
        asset.warnings.iter().any(|w| w.contains("skin 1 has joints outside the skeleton")),
        "{:?}",
        asset.warnings
    );

    // The two armatures under one scene node: one skeleton with two roots, both skinned.
    let mut grouped = hero;
    grouped[1] = r#"{"name": "hero_spine", "translation": [0, 0.5, 0]}"#;
    grouped[4] = r#"{"name": "stage", "children": [0, 2]}"#;
    let path = write("one_stage.gltf", two_skinned_meshes(grouped, "[6, 4, 5]", ["[0, 1]", "[2, 3]"]));
    let error = load_character(&path, 0).map(|_| ()).unwrap_err();
    println!("{error}");
    assert!(
        error.message.contains("holds 2 skeletons") && error.message.contains("hero_root, sidekick_root"),
        "{error}"
    );

    // One armature, a skin per mesh, the second's with the jaw: one character.
    let path = write("one_character.gltf", two_skinned_meshes(hero, "[0, 4, 5]", ["[0, 1]", "[6, 0, 1]"]));
    let character = load_character(&path, 0).unwrap().value;
    let skeleton = character.clip.skeleton();
    assert!(
        skeleton.index_of("hero_jaw").is_some(),
        "{:?}",
        skeleton.joints().iter().map(|j| &j.name).collect::<Vec<_>>()
    );
    let bindings: Vec<&str> = character.parts.iter().map(|p| p.binding.as_str()).collect();
    assert_eq!(bindings, ["skinned", "skinned"]);
    // The second mesh's vertices hang on the jaw (its skin's first joint).
    let jaw = skeleton.index_of("hero_jaw").unwrap();
    let skin = character.mesh.skin.as_ref().unwrap();
    assert!(skin.joints[3..].iter().all(|j| usize::from(j[0]) == jaw), "{:?}", &skin.joints[3..]);
}

/// Issue 18, the reference pose as a choice: `character.load` with `rest_pose: bind` rests
/// CesiumMan's skeleton in its skin's bind pose. Read independently with the `gltf` crate,
/// every joint of the skin stands where its inverse bind matrix, inverted and placed by the
/// Z-up armature node above the skeleton, puts it (within 1e-5 m), and the mesh at rest is
/// the file's vertex positions placed by their node (a skin binds the mesh as modelled).
/// CesiumMan and Xbot were saved in their bind poses: both choices agree on them.
#[test]
fn cesium_man_rests_in_its_bind_pose_on_request() {
    use kinegraph_nodes::kernels::load::{RestPose, load_character_resting};
    use kinegraph_nodes::model::fk::rest_world;
    let Some(data) = shared_data() else { return };
    let path = data.join("gltf/CesiumMan.glb");
    let nodes = load_character_resting(&path, 0, RestPose::Nodes).unwrap().value;
    let bind = load_character_resting(&path, 0, RestPose::Bind).unwrap().value;
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let world = gltf_validator::rest_worlds(&doc);
    let skin = doc.skins().next().unwrap();
    let top = skin.joints().next().unwrap().index();
    let armature = doc.nodes().find(|n| n.children().any(|c| c.index() == top)).unwrap();
    let ibms = gltf_validator::inverse_bind_matrices(&skin, &buffers);
    let skeleton = bind.clip.skeleton();
    let (rest, node_rest) = (rest_world(skeleton), rest_world(nodes.clip.skeleton()));
    let (mut worst, mut moved) = (0.0f32, 0.0f32);
    for (joint, ibm) in skin.joints().zip(&ibms) {
        let j = skeleton.index_of(joint.name().unwrap()).unwrap();
        let want = (world[armature.index()] * ibm.inverse()).w_axis.truncate();
        worst = worst.max(rest[j].translation.distance(want));
        moved = moved.max(node_rest[j].translation.distance(rest[j].translation));
    }
    println!("bind rest: joints within {worst:.2e} m of their bind pose; the node rest differs by up to {moved:.1e} m");
    assert!(worst < 1e-5, "{worst}");

    // The mesh at rest: the file's POSITION values placed by their node, in file order.
    let mut modelled = Vec::new();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        for primitive in mesh.primitives() {
            let positions = primitive.reader(|b| Some(&buffers[b.index()])).read_positions().unwrap();
            modelled.extend(positions.map(|p| world[node.index()].transform_point3(Vec3::from(p))));
        }
    }
    assert_eq!(modelled.len(), bind.mesh.positions.len());
    let off = modelled.iter().zip(&bind.mesh.positions).map(|(a, b)| a.distance(*b)).fold(0.0f32, f32::max);
    println!("mesh at bind rest: within {off:.2e} m of the mesh as modelled");
    assert!(off < 1e-5, "{off}");

    let xbot = data.join("gltf/Xbot.glb");
    let (a, b) = (
        load_character_resting(&xbot, 0, RestPose::Nodes).unwrap().value,
        load_character_resting(&xbot, 0, RestPose::Bind).unwrap().value,
    );
    let (ra, rb) = (rest_world(a.clip.skeleton()), rest_world(b.clip.skeleton()));
    let apart = ra.iter().zip(&rb).map(|(x, y)| x.translation.distance(y.translation)).fold(0.0f32, f32::max);
    println!("Xbot: bind and node rest poses within {apart:.2e} m");
    assert!(apart < 1e-4, "{apart}");
}

/// `rest_pose: bind` on a file saved with its arm posed: a root at 1 m and an arm joint
/// 0.5 m out along X, turned 90° about Z in the node transforms, bound straight (inverse bind
/// matrices of the unturned joints), and a badge mesh hung on the arm node. Hand-solved:
/// resting in the bind pose, the arm joint has no turn, the triangle skinned to it stays
/// where it is stored and the badge hangs straight out; resting in the node transforms, the
/// arm is turned and both swing up about the arm joint.
#[test]
fn a_file_saved_posed_rests_in_its_bind_pose_on_request() {
    use base64::Engine as _;
    use kinegraph_nodes::kernels::load::{RestPose, load_character_resting};
    let stored = [Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 1.1, 0.0), Vec3::new(0.9, 1.0, 0.0)];
    let mut bin = Vec::new();
    for v in stored.iter().flat_map(|p| p.to_array()) {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    bin.extend_from_slice(&[1, 0, 0, 0].repeat(3));
    for _ in 0..3 {
        for w in [1.0f32, 0.0, 0.0, 0.0] {
            bin.extend_from_slice(&w.to_le_bytes());
        }
    }
    for ibm in [Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0)), Mat4::from_translation(Vec3::new(-0.5, -1.0, 0.0))] {
        for v in ibm.to_cols_array() {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let badge = [Vec3::new(0.2, 0.0, 0.0), Vec3::new(0.3, 0.0, 0.0), Vec3::new(0.2, 0.1, 0.0)];
    for v in badge.iter().flat_map(|p| p.to_array()) {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&bin);
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 2]}}],
  "nodes": [
    {{"name": "root", "translation": [0, 1, 0], "children": [1]}},
    {{"name": "arm", "translation": [0.5, 0, 0], "rotation": [0, 0, 0.70710678, 0.70710678], "children": [3]}},
    {{"name": "body", "mesh": 0, "skin": 0}},
    {{"name": "badge", "mesh": 1}}
  ],
  "skins": [{{"joints": [0, 1], "inverseBindMatrices": 4}}],
  "meshes": [{{"name": "body", "primitives": [{{"attributes": {{"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}}, "indices": 1}}]}},
             {{"name": "badge", "primitives": [{{"attributes": {{"POSITION": 5}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}},
                  {{"buffer": 0, "byteOffset": 44, "byteLength": 12}}, {{"buffer": 0, "byteOffset": 56, "byteLength": 48}},
                  {{"buffer": 0, "byteOffset": 104, "byteLength": 128}}, {{"buffer": 0, "byteOffset": 232, "byteLength": 36}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.9, 1, 0], "max": [1, 1.1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}},
    {{"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"}},
    {{"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}},
    {{"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"}},
    {{"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.2, 0, 0], "max": [0.3, 0.1, 0]}}
  ]
}}"#,
        len = bin.len()
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("posed.gltf");
    std::fs::write(&path, gltf).unwrap();
    let bind = load_character_resting(&path, 0, RestPose::Bind).unwrap().value;
    let nodes = load_character_resting(&path, 0, RestPose::Nodes).unwrap().value;
    let arm = bind.clip.skeleton().index_of("arm").unwrap();
    let close = |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).all(|(x, y)| x.distance(*y) < 1e-6);
    assert!(bind.clip.skeleton().joints()[arm].rest_rotation.angle_between(Quat::IDENTITY) < 1e-6);
    // The badge straight out from the arm joint at (0.5, 1, 0) in the bind pose.
    let hung: Vec<Vec3> = badge.iter().map(|p| *p + Vec3::new(0.5, 1.0, 0.0)).collect();
    let at_rest: Vec<Vec3> = stored.iter().chain(&hung).copied().collect();
    assert!(close(&bind.mesh.positions, &at_rest), "{:?}", bind.mesh.positions);
    // Turned 90° about Z at (0.5, 1, 0): (x, y) → (0.5 − (y − 1), 1 + (x − 0.5)).
    let swing = |p: &Vec3| Vec3::new(0.5 - (p.y - 1.0), 1.0 + (p.x - 0.5), 0.0);
    let swung: Vec<Vec3> = at_rest.iter().map(swing).collect();
    assert!(close(&nodes.mesh.positions, &swung), "{:?}", nodes.mesh.positions);
}

/// Issue 18, a bone-attached mesh on a sample rig: Xbot (its two skinned meshes) with a
/// helmet plate added as a mesh node under its `mixamorig:Head` node (in the head's
/// centimetre frame, 20 cm up). `character.load` binds the plate rigidly to the head and puts
/// it where the `gltf` crate, reading the same file, places it through the node hierarchy
/// (within 1e-5 m); the skinned meshes stay skinned, and the export validates.
#[test]
fn a_prop_parented_to_xbots_head_follows_the_head() {
    use base64::Engine as _;
    use kinegraph_nodes::kernels::load::load_character;
    let Some(data) = shared_data() else { return };
    let glb = gltf::Gltf::open(data.join("gltf/Xbot.glb")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("xbot.bin"), glb.blob.as_ref().unwrap()).unwrap();
    let mut json = serde_json::to_value(glb.document.clone().into_json()).unwrap();
    json["buffers"][0]["uri"] = "xbot.bin".into();
    // The plate: one triangle, 10 cm wide, in its node's (the head's centimetre) frame.
    let corners = [[-5.0f32, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 0.0, 8.0]];
    let mut bin: Vec<u8> = corners.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    bin.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
    let count = |key: &str| json[key].as_array().map_or(0, Vec::len);
    let (buffer, view, accessor, mesh, node) =
        (count("buffers"), count("bufferViews"), count("accessors"), count("meshes"), count("nodes"));
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    json["buffers"].as_array_mut().unwrap().push(serde_json::json!({"byteLength": bin.len(), "uri": uri}));
    json["bufferViews"].as_array_mut().unwrap().extend([
        serde_json::json!({"buffer": buffer, "byteOffset": 0, "byteLength": 36}),
        serde_json::json!({"buffer": buffer, "byteOffset": 36, "byteLength": 6}),
    ]);
    json["accessors"].as_array_mut().unwrap().extend([
        serde_json::json!({"bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [-5.0, 0.0, 0.0], "max": [5.0, 0.0, 8.0]}),
        serde_json::json!({"bufferView": view + 1, "componentType": 5123, "count": 3, "type": "SCALAR"}),
    ]);
    json["meshes"].as_array_mut().unwrap().push(serde_json::json!(
        {"name": "helmet", "primitives": [{"attributes": {"POSITION": accessor}, "indices": accessor + 1}]}));
    json["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"name": "helmet", "mesh": mesh, "translation": [0, 20, 0]}));
    let head = json["nodes"].as_array().unwrap().iter().position(|n| n["name"] == "mixamorig:Head").unwrap();
    let children =
        json["nodes"][head].as_object_mut().unwrap().entry("children").or_insert_with(|| serde_json::json!([]));
    children.as_array_mut().unwrap().push(node.into());
    let path = dir.path().join("xbot_helmet.gltf");
    std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();

    let loaded = load_character(&path, 0).unwrap().value;
    let bindings: Vec<(&str, &str)> = loaded.parts.iter().map(|p| (p.name.as_str(), p.binding.as_str())).collect();
    println!("parts: {bindings:?}");
    assert_eq!(bindings.iter().filter(|(_, b)| *b == "skinned").count(), 2);
    let helmet = loaded.parts.iter().position(|p| p.name == "helmet").expect("the helmet part");
    assert_eq!(loaded.parts[helmet].binding, "rigid to mixamorig:Head");
    let first: usize = loaded.parts[..helmet].iter().map(|p| p.vertices).sum();
    let skin = loaded.mesh.skin.as_ref().unwrap();
    let head_joint = loaded.clip.skeleton().index_of("mixamorig:Head").unwrap();
    assert!(skin.joints[first..first + 3].iter().all(|j| usize::from(j[0]) == head_joint));
    let (doc, _, _) = gltf::import(&path).unwrap();
    let world = gltf_validator::rest_worlds(&doc);
    let worst = corners
        .iter()
        .zip(&loaded.mesh.positions[first..first + 3])
        .map(|(c, p)| world[node].transform_point3(Vec3::from(*c)).distance(*p))
        .fold(0.0f32, f32::max);
    println!("helmet at rest within {worst:.2e} m of where the node hierarchy puts it");
    assert!(worst < 1e-5, "{worst}");
    let out = dir.path().join("xbot_helmet.glb");
    write_glb_file(&out, &loaded.clip, Some(&loaded.mesh)).unwrap();
    gltf_validator::validate_gltf(&[out]);
}
