//! Issue 18: whole characters keep their look through `character.load` → `export.glb`.
//! Both the source file and the exported GLB are read here with the `gltf` crate (not
//! kinegraph's reader) and drawn the way a viewer draws them at rest: linear blend skinning
//! with the nodes' rest transforms and the file's inverse bind matrices. Per material, the
//! two must hold the same parameters, the same image bytes, the same triangles (rest-pose
//! corners within 1e-5 m) and the same UVs; the Khronos validator must report 0 errors.
//! Mixamo FBX downloads are read for comparison with ufbx alone, as modelled.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed unwrap is a failed test

mod gltf_validator;

use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{Mat4, Vec2, Vec3};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::gltf::write_glb_file;
use kinegraph_nodes::kernels::load::load_character;

/// What a viewer needs of a texture: the image's bytes (their length and SipHash), the
/// sampler and the UV set.
#[derive(Debug, PartialEq)]
struct TextureFacts {
    bytes: (usize, u64),
    mime: Option<String>,
    sampler: (Option<u32>, Option<u32>, u32, u32),
    tex_coord: u32,
}

/// A material's parameters as the `gltf` crate reads them.
#[derive(Debug, PartialEq)]
struct MaterialFacts {
    name: Option<String>,
    base_color: [f32; 4],
    metallic: f32,
    roughness: f32,
    emissive: [f32; 3],
    alpha: String,
    double_sided: bool,
    normal_scale: Option<f32>,
    occlusion_strength: Option<f32>,
    specular: Option<(f32, [f32; 3])>,
    /// Base colour, metallic-roughness, normal, occlusion and emissive textures.
    textures: [Option<TextureFacts>; 5],
}

/// The triangles a material draws: rest-pose corners (metres) and their UVs.
#[derive(Debug)]
struct Drawn {
    material: MaterialFacts,
    corners: Vec<[Vec3; 3]>,
    uvs: Vec<[Vec2; 3]>,
}

fn image_bytes(image: gltf::Image<'_>, buffers: &[gltf::buffer::Data], base: &Path) -> (Vec<u8>, Option<String>) {
    match image.source() {
        gltf::image::Source::View { view, mime_type } => {
            let buffer = &buffers[view.buffer().index()];
            (buffer[view.offset()..view.offset() + view.length()].to_vec(), Some(mime_type.to_owned()))
        }
        gltf::image::Source::Uri { uri, mime_type } => match uri.strip_prefix("data:") {
            Some(rest) => {
                let (meta, payload) = rest.split_once(',').unwrap();
                let mime = meta.strip_suffix(";base64").unwrap().to_owned();
                (base64::engine::general_purpose::STANDARD.decode(payload).unwrap(), Some(mime))
            }
            // Without a mimeType a viewer goes by the file's extension.
            None => {
                let mime = mime_type.map(str::to_owned).or_else(|| uri.ends_with(".png").then(|| "image/png".into()));
                (std::fs::read(base.join(uri.replace("%20", " "))).unwrap(), mime)
            }
        },
    }
}

/// Length and hash of `bytes`: equal for equal images (a collision of both is not a
/// concern for a handful of images).
fn fingerprint(bytes: &[u8]) -> (usize, u64) {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut h);
    (bytes.len(), h.finish())
}

fn texture_facts(
    texture: Option<(gltf::Texture<'_>, u32)>,
    buffers: &[gltf::buffer::Data],
    base: &Path,
) -> Option<TextureFacts> {
    let (t, tex_coord) = texture?;
    let s = t.sampler();
    let (bytes, mime) = image_bytes(t.source(), buffers, base);
    Some(TextureFacts {
        bytes: fingerprint(&bytes),
        mime,
        sampler: (
            s.mag_filter().map(|f| f.as_gl_enum()),
            s.min_filter().map(|f| f.as_gl_enum()),
            s.wrap_s().as_gl_enum(),
            s.wrap_t().as_gl_enum(),
        ),
        tex_coord,
    })
}

fn info(i: Option<gltf::texture::Info<'_>>) -> Option<(gltf::Texture<'_>, u32)> {
    i.map(|i| (i.texture(), i.tex_coord()))
}

fn material_facts(m: gltf::Material<'_>, buffers: &[gltf::buffer::Data], base: &Path) -> MaterialFacts {
    let pbr = m.pbr_metallic_roughness();
    MaterialFacts {
        name: m.name().map(str::to_owned),
        base_color: pbr.base_color_factor(),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        emissive: m.emissive_factor(),
        alpha: format!("{:?} {:?}", m.alpha_mode(), m.alpha_cutoff()),
        double_sided: m.double_sided(),
        normal_scale: m.normal_texture().map(|n| n.scale()),
        occlusion_strength: m.occlusion_texture().map(|o| o.strength()),
        specular: m.specular().map(|s| (s.specular_factor(), s.specular_color_factor())),
        textures: [
            texture_facts(info(pbr.base_color_texture()), buffers, base),
            texture_facts(info(pbr.metallic_roughness_texture()), buffers, base),
            texture_facts(m.normal_texture().map(|n| (n.texture(), n.tex_coord())), buffers, base),
            texture_facts(m.occlusion_texture().map(|o| (o.texture(), o.tex_coord())), buffers, base),
            texture_facts(info(m.emissive_texture()), buffers, base),
        ],
    }
}

/// Every primitive of `path`'s default scene drawn at rest, grouped by material in the
/// order the materials first appear (nodes in index order), read with the `gltf` crate.
fn drawn_at_rest(path: &Path) -> Vec<Drawn> {
    let gltf = gltf::Gltf::open(path).unwrap();
    let base = path.parent().unwrap();
    let buffers = gltf::import_buffers(&gltf.document, Some(base), gltf.blob.clone()).unwrap();
    let doc = &gltf.document;
    let world = gltf_validator::rest_worlds(doc);
    let mut groups: Vec<Drawn> = Vec::new();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let skinning: Option<Vec<Mat4>> =
            node.skin().map(|skin| gltf_validator::skin_matrices(&skin, &buffers, &world));
        for prim in mesh.primitives() {
            let r = prim.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
            let at_rest: Vec<Vec3> = match &skinning {
                Some(m) => {
                    let joints: Vec<[u16; 4]> = r.read_joints(0).unwrap().into_u16().collect();
                    let weights: Vec<[f32; 4]> = r.read_weights(0).unwrap().into_f32().collect();
                    positions
                        .iter()
                        .enumerate()
                        .map(|(v, p)| {
                            (0..4).map(|k| weights[v][k] * m[joints[v][k] as usize].transform_point3(*p)).sum()
                        })
                        .collect()
                }
                None => positions.iter().map(|p| world[node.index()].transform_point3(*p)).collect(),
            };
            let uvs: Option<Vec<Vec2>> = r.read_tex_coords(0).map(|t| t.into_f32().map(Vec2::from).collect());
            let indices: Vec<u32> = match r.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            let material = material_facts(prim.material(), &buffers, base);
            let k = match groups.iter().position(|g| g.material == material) {
                Some(k) => k,
                None => {
                    groups.push(Drawn { material, corners: Vec::new(), uvs: Vec::new() });
                    groups.len() - 1
                }
            };
            for t in indices.chunks_exact(3) {
                groups[k].corners.push([0, 1, 2].map(|c| at_rest[t[c] as usize]));
                if let Some(uv) = &uvs {
                    groups[k].uvs.push([0, 1, 2].map(|c| uv[t[c] as usize]));
                }
            }
        }
    }
    groups
}

/// The exported file draws what the source draws: per material the same parameters and
/// image bytes, the same triangles in the same order (corners within `tolerance_m`) and
/// the same UVs. Returns the worst corner distance (metres).
fn assert_same_look(source: &Path, exported: &Path, tolerance_m: f32) -> f32 {
    let (a, b) = (drawn_at_rest(source), drawn_at_rest(exported));
    let name = source.display();
    assert_eq!(a.len(), b.len(), "{name}: materials");
    let mut worst = 0.0f32;
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.material, y.material, "{name}");
        assert_eq!(x.corners.len(), y.corners.len(), "{name}: triangles of {:?}", x.material.name);
        for (cx, cy) in x.corners.iter().zip(&y.corners) {
            for c in 0..3 {
                worst = worst.max(cx[c].distance(cy[c]));
            }
        }
        assert_eq!(x.uvs, y.uvs, "{name}: UVs of {:?}", x.material.name);
        let images: Vec<(usize, u64)> = x.material.textures.iter().flatten().map(|t| t.bytes).collect();
        println!(
            "{name}: material {:?}: {} triangles, {} UV triangles, images (bytes, hash) {images:?}",
            x.material.name,
            x.corners.len(),
            x.uvs.len()
        );
    }
    println!("{name}: worst rest-pose corner distance {worst:.2e} m");
    assert!(worst < tolerance_m, "{name}: {worst} m");
    worst
}

/// A mesh object as a viewer lists it.
#[derive(Debug, PartialEq)]
struct MeshObject {
    node: Option<String>,
    mesh: Option<String>,
    triangles: usize,
    /// Joints of its skin (`None`: not skinned).
    skin_joints: Option<usize>,
}

/// The mesh objects of a file read with the `gltf` crate: one per node holding a mesh,
/// nodes in index order.
fn mesh_objects(path: &Path) -> Vec<MeshObject> {
    let gltf = gltf::Gltf::open(path).unwrap();
    let mut objects = Vec::new();
    for node in gltf.document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let corners = |p: gltf::Primitive<'_>| {
            p.indices().map_or_else(|| p.get(&gltf::Semantic::Positions).unwrap().count(), |i| i.count())
        };
        let triangles = mesh.primitives().map(|p| corners(p) / 3).sum();
        objects.push(MeshObject {
            node: node.name().map(str::to_owned),
            mesh: mesh.name().map(str::to_owned),
            triangles,
            skin_joints: node.skin().map(|s| s.joints().count()),
        });
    }
    objects
}

#[test]
fn corpus_characters_keep_materials_textures_and_uvs_through_export() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    // CesiumMan: one JPEG base-colour texture; Fox: one PNG; Xbot: two untextured
    // materials with KHR_materials_specular, one per mesh.
    for name in ["CesiumMan.glb", "Fox.glb", "Xbot.glb"] {
        let source = data.join("gltf").join(name);
        let character = load_character(&source, 0).unwrap().value;
        let out = dir.path().join(format!("{name}.character.glb"));
        write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
        // Fox is ~150 units tall in a file declared metres: f32 resolution scales with it.
        let tolerance = if name == "Fox.glb" { 1e-3 } else { 1e-5 };
        assert_same_look(&source, &out, tolerance);
        // The same mesh objects, one per source mesh, under the same names and skin.
        let (a, b) = (mesh_objects(&source), mesh_objects(&out));
        println!("{name}: mesh objects {a:?}");
        assert_eq!(a, b, "{name}: mesh objects of the source, then of the export");
        files.push(out);
    }
    let drawn = drawn_at_rest(&files[0]);
    assert!(drawn[0].material.textures[0].as_ref().is_some_and(|t| t.mime.as_deref() == Some("image/jpeg")));
    gltf_validator::validate_gltf(&files);
}

/// A two-joint rig with a textured triangle hanging from its bone (`character.load` binds
/// it rigidly), its base-colour image at `uri`.
fn textured_prop(uri: &str) -> String {
    // Positions (3 × VEC3), indices (3 × u16 + 2 padding), UVs (3 × VEC2).
    let mut bin = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    for v in [0.0f32, 0.0, 1.0, 0.0, 0.25, 0.75] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    let data = base64::engine::general_purpose::STANDARD.encode(&bin);
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"name": "root", "translation": [0, 1, 0], "children": [1]}},
    {{"name": "bone", "translation": [0, 1, 0], "children": [2]}},
    {{"name": "badge", "translation": [0.5, 0, 0], "mesh": 0}}
  ],
  "skins": [{{"joints": [0, 1]}}],
  "meshes": [{{"name": "badge", "primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 2}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{"name": "badge_paint", "pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}, "metallicFactor": 0.25, "roughnessFactor": 0.75}},
                  "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true, "emissiveFactor": [0.1, 0.2, 0.3]}}],
  "textures": [{{"source": 0, "sampler": 0}}],
  "samplers": [{{"magFilter": 9728, "wrapS": 33071, "wrapT": 33648}}],
  "images": [{{"uri": "{uri}"}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}, {{"buffer": 0, "byteOffset": 44, "byteLength": 24}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}},
    {{"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}}
  ]
}}"#,
        len = bin.len()
    )
}

/// The PNG of the Fox sample, as stored in its GLB.
fn fox_png(data: &Path) -> Vec<u8> {
    let path = data.join("gltf/Fox.glb");
    let gltf = gltf::Gltf::open(&path).unwrap();
    let buffers = gltf::import_buffers(&gltf.document, None, gltf.blob.clone()).unwrap();
    image_bytes(gltf.document.images().next().unwrap(), &buffers, Path::new(".")).0
}

/// Images given as a file beside the glTF (a percent-encoded name in a subfolder) and as a
/// `data:` URI are embedded byte for byte in the exported GLB, with the material's
/// parameters and sampler; a missing image file stops `character.load` with an error that
/// names the file.
#[test]
fn images_from_files_and_data_uris_are_embedded_and_a_missing_one_is_named() {
    let Some(data) = shared_data() else { return };
    let png = fox_png(&data);
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("maps")).unwrap();
    std::fs::write(dir.path().join("maps/badge paint.png"), &png).unwrap();
    let data_uri = format!("data:image/png;base64,{}", base64::engine::general_purpose::STANDARD.encode(&png));
    let mut files = Vec::new();
    for (name, uri) in [("file", "maps/badge%20paint.png"), ("data_uri", data_uri.as_str())] {
        let source = dir.path().join(format!("{name}.gltf"));
        std::fs::write(&source, textured_prop(uri)).unwrap();
        let character = load_character(&source, 0).unwrap().value;
        assert_eq!(character.parts[0].binding, "rigid to bone");
        let out = dir.path().join(format!("{name}.glb"));
        write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
        assert_same_look(&source, &out, 1e-6);
        let drawn = drawn_at_rest(&out);
        let texture = drawn[0].material.textures[0].as_ref().unwrap();
        assert_eq!(texture.bytes, fingerprint(&png), "{name}");
        // Hand-written in the JSON above: NEAREST, no min filter, CLAMP_TO_EDGE, MIRRORED_REPEAT.
        assert_eq!(texture.sampler, (Some(9728), None, 33071, 33648));
        assert_eq!(drawn[0].material.alpha, "Mask Some(0.3)");
        files.push(out);
    }
    gltf_validator::validate_gltf(&files);

    let missing = dir.path().join("missing.gltf");
    std::fs::write(&missing, textured_prop("maps/gone.png")).unwrap();
    let err = load_character(&missing, 0).unwrap_err();
    let text = err.to_string();
    println!("missing image: {text}");
    assert!(text.contains("missing.gltf") && text.contains("/images/0/uri") && text.contains("gone.png"), "{text}");
}

/// A character without materials exports as before: one primitive, no material, no image.
#[test]
fn a_character_without_materials_writes_none() {
    let Some(data) = shared_data() else { return };
    let source: PathBuf = data.join("gltf/SimpleSkin.gltf");
    let character = load_character(&source, 0).unwrap().value;
    assert!(character.mesh.materials.is_empty() && character.mesh.material_ranges.is_empty());
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("simple.glb");
    write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
    let (doc, _, images) = gltf::import(&out).unwrap();
    assert_eq!((doc.materials().count(), images.len()), (0, 0));
    let prims: Vec<_> = doc.meshes().flat_map(|m| m.primitives()).collect();
    assert_eq!(prims.len(), 1);
    assert!(prims[0].material().index().is_none());
}

/// What an FBX file's meshes draw as modelled, read with ufbx alone (not kinegraph's
/// reader): per material name, each face triangulated by ufbx in file order, its corners
/// placed by the mesh node's geometry-to-world matrix (the undeformed mesh, where the skin
/// binds it), its UVs with V flipped to glTF's convention; and the fingerprint of the base
/// colour texture's embedded bytes.
type FbxDrawn = Vec<(String, Vec<[Vec3; 3]>, Vec<[Vec2; 3]>, Option<(usize, u64)>)>;

fn fbx_drawn_as_modelled(path: &Path) -> FbxDrawn {
    let opts = ufbx::LoadOpts {
        target_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_unit_meters: 1.0,
        space_conversion: ufbx::SpaceConversion::AdjustTransforms,
        handedness_conversion_axis: ufbx::MirrorAxis::Z,
        ..Default::default()
    };
    let scene = ufbx::load_memory(&std::fs::read(path).unwrap(), opts).unwrap();
    let mut groups: FbxDrawn = Vec::new();
    for node in scene.nodes.iter() {
        let Some(mesh) = node.mesh.as_ref() else { continue };
        let m = &node.geometry_to_world;
        let world = Mat4::from_cols_array(
            &[m.m00, m.m10, m.m20, 0.0, m.m01, m.m11, m.m21, 0.0, m.m02, m.m12, m.m22, 0.0, m.m03, m.m13, m.m23, 1.0]
                .map(|v| v as f32),
        );
        let materials = if node.materials.is_empty() { &mesh.materials } else { &node.materials };
        let mut corners = vec![0u32; 3 * mesh.max_face_triangles];
        for (f, face) in mesh.faces.iter().enumerate() {
            let material = &materials[mesh.face_material[f] as usize];
            let name = material.element.name.to_string();
            let k = groups.iter().position(|g| g.0 == name).unwrap_or_else(|| {
                let texture = material.pbr.base_color.texture.as_ref().map(|t| {
                    let bytes: &[u8] =
                        if t.content.is_empty() { &t.video.as_ref().unwrap().content } else { &t.content };
                    fingerprint(bytes)
                });
                groups.push((name, Vec::new(), Vec::new(), texture));
                groups.len() - 1
            });
            let n = mesh.triangulate_face(&mut corners, *face) as usize;
            for t in corners[..3 * n].chunks_exact(3) {
                groups[k].1.push([0, 1, 2].map(|c| {
                    let p = mesh.vertex_position[t[c] as usize];
                    world.transform_point3(Vec3::new(p.x as f32, p.y as f32, p.z as f32))
                }));
                groups[k].2.push([0, 1, 2].map(|c| {
                    let uv = mesh.vertex_uv[t[c] as usize];
                    Vec2::new(uv.x as f32, 1.0 - uv.y as f32)
                }));
            }
        }
    }
    groups
}

/// Issue 18, Mixamo FBX in, GLB out, the same look: for each of the corpus's Mixamo
/// downloads, the exported GLB drawn at rest through its skin (the `gltf` crate) holds, per
/// material, the triangles ufbx reads from the FBX as modelled, in the same order (corners
/// within 1e-5 m), with the same UVs (within 1e-6), and the FBX's embedded base colour
/// image byte for byte; the validator reports 0 errors.
#[test]
fn mixamo_fbx_characters_keep_their_look_through_export() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for name in ["standard_walk.fbx", "jab_cross.fbx", "jumping.fbx"] {
        let source = data.join("fbx").join(name);
        let character = load_character(&source, 0).unwrap().value;
        let out = dir.path().join(format!("{name}.glb"));
        write_glb_file(&out, &character.clip, Some(&character.mesh)).unwrap();
        let fbx = fbx_drawn_as_modelled(&source);
        let glb = drawn_at_rest(&out);
        assert_eq!(fbx.len(), glb.len(), "{name}: materials");
        let (mut worst, mut worst_uv) = (0.0f32, 0.0f32);
        for (material, corners, uvs, texture) in &fbx {
            let drawn = glb.iter().find(|g| g.material.name.as_ref() == Some(material)).expect("material by name");
            assert_eq!(drawn.material.textures[0].as_ref().map(|t| t.bytes), *texture, "{name}: {material}'s image");
            assert_eq!(drawn.corners.len(), corners.len(), "{name}: triangles of {material}");
            for ((a, b), (ua, ub)) in corners.iter().zip(&drawn.corners).zip(uvs.iter().zip(&drawn.uvs)) {
                for c in 0..3 {
                    worst = worst.max(a[c].distance(b[c]));
                    worst_uv = worst_uv.max(ua[c].distance(ub[c]));
                }
            }
            println!("{name}: material '{material}': {} triangles, image {texture:?}", corners.len());
        }
        println!("{name}: worst corner distance {worst:.2e} m, worst UV distance {worst_uv:.2e}");
        assert!(worst < 1e-5 && worst_uv < 1e-6, "{name}: {worst} m, UV {worst_uv}");
        files.push(out);
    }
    gltf_validator::validate_gltf(&files);
}
