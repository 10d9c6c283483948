//! Kernels: the motion operations several node families share, below the node contract.
//!
//! Pure functions over the model's types (skeletons, clips, meshes) that return new data.
//! A kernel imports only `math`, `model`, `formats` and other kernels, never the node
//! contract (`node`) or a node family (`builtin`); a family imports kernels, never another
//! family. `nodes/tests/layers.rs` checks both.
//!
//! | concept | module |
//! |---|---|
//! | body mass model, landmarks, limb tips (de Leva) | [`body`] |
//! | body roles of a humanoid by name or shape | [`roles`] |
//! | foot contacts and ground height | [`contacts`] |
//! | angular momentum, central differences | [`angular`] |
//! | momentum phases | [`phases`] |
//! | a clip analysed once for joining | [`analysis`] |
//! | heading alignment of two motions | [`align`] |
//! | blend-and-splice, foot skate, join result | [`join`] |
//! | the Motion-Graphs crossfade baseline | [`baseline`] |
//! | motion quality measures and gates (skate, floor, spikes, pops) | [`quality`] |
//! | stride: step length ÷ leg length, pelvis speed range | [`stride`] |
//! | ground / flight stages, ballistic gravity fit | [`stages`] |
//! | momentum pre-fit: flight lines, ground B-splines | [`momentum_splines`] |
//! | ground-stage edits, the naive edit (initial guess), edit measures | [`momentum_edit`] |
//! | the edit's solver: augmented Lagrangian, Gauss-Newton, sparse Cholesky | [`momentum_solve`] |
//! | motion families: one stage swept, samples optimised in parallel | [`family`] |
//! | family blend of the 2^n nearest samples, inverse control | [`family_blend`] |
//! | IK rig, weighted Jacobian solver, foot lock | [`ik`] |
//! | resampling | [`resample`] |
//! | skinning matrices, LBS, automatic weights | [`skinning`] |
//! | skinned soles: the lowest vertex of each foot per frame | [`soles`] |
//! | pose vectors | [`pose_vector`] |
//! | generated figures (arm, mannequin) | [`arm`], [`mannequin`] |
//! | loading clips, meshes and clip sets | [`load`], [`clip_set`] |
//! | transition-graph types and search | [`transition_graph`] |
//! | smoke on dynamic tetrahedral meshes (Klingner 2006) | [`fluid`] |
//! | rigid-body physics on rapier3d: world, figures, controllers | [`physics`] |
//! | wrap deformer: binding through a triangle hierarchy, per-frame replay | [`wrap`] |

pub mod align;
pub mod analysis;
pub mod angular;
pub mod arm;
pub mod baseline;
pub mod body;
pub mod clip_set;
pub mod contacts;
pub mod family;
pub mod family_blend;
pub mod fluid;
pub mod ik;
pub mod join;
pub mod load;
pub mod mannequin;
pub mod momentum_edit;
pub mod momentum_solve;
pub mod momentum_splines;
pub mod phases;
pub mod physics;
pub mod pose_vector;
pub mod props;
pub mod quality;
pub mod resample;
pub mod roles;
pub mod skinning;
pub mod soles;
pub mod stages;
pub mod stride;
pub mod transition_graph;
pub mod wrap;
