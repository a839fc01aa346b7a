// `amt refit-garment`: a garment designed on a source avatar moved onto a target avatar of other
// proportions, intersection-free (refit/garment_refit.h, the garment-refit paper). Prints the inputs, a
// progress line per outer iteration and per Newton step of the fit, and a summary.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "app/commands.h"
#include "data_tools/builder/apparel.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/formats/render.h"
#include "data_tools/geometry/error.h"
#include "infer/character_input.h"
#include "refit/garment_refit.h"
#include "refit/skeleton_shrink.h"

namespace amt::app {
namespace {

struct RefitCommandOptions {
  std::string garment, out, picture;
  float garment_share = 0.3f;  // a generated garment's share of the dressed mesh's vertices
  CharacterSpec source, target;
  refit::GarmentRefitOptions refit;
  bool quiet = false;
};

// An avatar on the canonical skeleton, with skinning weights over its joints.
struct Avatar {
  std::string name;
  TriMesh mesh;
  Skeleton skeleton;
  SparseWeights weights;
  std::optional<GeneratedBody> generated;  // a generated:SEED avatar's body
};

refit::Positions to_double(const MatrixX3f& V) {
  return V.cast<double>();
}

// Weights of a mesh without its own: each vertex rigidly on the joint that drives its nearest bone (a joint
// drives the bone towards its child, as in the generated bodies).
SparseWeights nearest_bone_weights(const TriMesh& mesh, const Skeleton& skeleton) {
  const MatrixX2i bones = refit::skeleton_bones(skeleton.parents);
  const std::vector<int> nearest = refit::nearest_bones(to_double(mesh.V), to_double(skeleton.rest_joints), bones);
  MatrixXfR W = MatrixXfR::Zero(mesh.num_vertices(), skeleton.num_joints());
  for (int v = 0; v < mesh.num_vertices(); ++v) W(v, bones(nearest[v], 0)) = 1.0f;
  return sparsify_weights(W);
}

// "generated:SEED[:VERTICES]" is the dataset builder's generated body, without apparel (the garment dresses
// it); every other spec is read as `amt animate` reads characters (infer/character_input.h).
Avatar load_avatar(const CharacterSpec& spec, const char* option) {
  Avatar a;
  if (spec.spec.rfind("generated:", 0) == 0) {
    unsigned long long seed = 0;
    int vertices = 3000;
    char tail = 0;
    const int got = std::sscanf(spec.spec.c_str() + 10, "%llu:%d%c", &seed, &vertices, &tail);
    AMT_CHECK(got == 1 || got == 2, option, " ", spec.spec, ": expected generated:SEED or generated:SEED:VERTICES");
    AMT_CHECK(vertices >= kMinBodyVertices && vertices <= kMaxBodyVertices, option, " ", spec.spec, ": expected ",
              kMinBodyVertices, " to ", kMaxBodyVertices, " vertices, found ", vertices);
    GeneratedBody body = generate_body(sample_body_params(uint64_t(seed)), vertices);
    a.name = "generated_" + std::to_string(seed);
    a.mesh = body.mesh;
    a.skeleton = body.skeleton;
    a.weights = body.weights;
    a.generated = std::move(body);
    return a;
  }
  const RuntimeCharacter c = [&] {
    try {
      return load_character(spec);
    } catch (const Error& e) {
      // Name this command's options in load_character's hints (it speaks of amt animate's --character-*).
      std::string message = e.what();
      const std::string side = std::string(option).substr(2);  // "source" or "target"
      for (const std::string hint : {"--character-joint-map", "--character-joints"}) {
        const size_t at = message.find(hint);
        if (at != std::string::npos) message.replace(at, hint.size(), "--" + side + hint.substr(11));
      }
      throw Error(message);
    }
  }();
  a.name = c.name;
  a.mesh = c.mesh;
  a.skeleton = c.skeleton;
  const std::string e = std::filesystem::path(spec.spec).extension().string();
  if (e == ".glb" || e == ".gltf" || e == ".GLB" || e == ".GLTF") {
    try {
      // The file's weights, each file joint's weight moved to the canonical joint that carries it.
      const GltfCharacter g = gltf_character(read_gltf(spec.spec));
      MatrixXfR W = MatrixXfR::Zero(g.mesh.num_vertices(), a.skeleton.num_joints());
      for (int v = 0; v < g.weights.num_vertices(); ++v)
        for (int k = 0; k < kMaxInfluences; ++k)
          W(v, c.rest.carrier[size_t(g.weights.indices(v, k))]) += g.weights.weights(v, k);
      if (W.rows() == a.mesh.num_vertices()) a.weights = sparsify_weights(W);
    } catch (const Error&) {
      // An unrigged glTF with a joints file: no weights of its own.
    }
  }
  if (a.weights.num_vertices() != a.mesh.num_vertices()) a.weights = nearest_bone_weights(a.mesh, a.skeleton);
  return a;
}

// A garment file, or "generated:KIND[:SEED]": the dataset builder's apparel piece of that kind dressed onto the
// (generated) source avatar, without its apparel bones.
TriMesh load_garment(const std::string& spec, const Avatar& source, float garment_share) {
  if (spec.rfind("generated:", 0) == 0) {
    const std::string rest = spec.substr(10);
    const std::string kind_name = rest.substr(0, rest.find(':'));
    unsigned long long seed = 1;
    if (rest.find(':') != std::string::npos) {
      char tail = 0;
      AMT_CHECK(std::sscanf(rest.c_str() + rest.find(':') + 1, "%llu%c", &seed, &tail) == 1, "--garment ", spec,
                ": expected generated:KIND or generated:KIND:SEED");
    }
    std::optional<ApparelKind> kind;
    std::string known;
    for (int k = 0; k < kApparelKindCount; ++k) {
      known += std::string(k ? ", " : "") + apparel_kind_name(ApparelKind(k));
      if (kind_name == apparel_kind_name(ApparelKind(k))) kind = ApparelKind(k);
    }
    AMT_CHECK(kind.has_value(), "--garment ", spec, ": kind '", kind_name, "', expected one of ", known);
    AMT_CHECK(source.generated.has_value(), "--garment ", spec,
              ": a generated garment is dressed onto the source avatar, expected --source generated:SEED, found ",
              source.name);
    ApparelOptions apparel;
    apparel.vertex_fraction = garment_share;
    const DressedCharacter dressed = dress_character_with(*source.generated, {*kind}, seed, apparel);
    const int first = source.mesh.num_vertices(), n = dressed.mesh.num_vertices() - first;
    TriMesh garment;
    garment.V = dressed.mesh.V.bottomRows(n);
    std::vector<int> faces;
    for (int f = 0; f < dressed.mesh.num_faces(); ++f)
      if (dressed.mesh.F.row(f).minCoeff() >= first) faces.push_back(f);
    garment.F.resize(int(faces.size()), 3);
    for (size_t i = 0; i < faces.size(); ++i) garment.F.row(int(i)) = dressed.mesh.F.row(faces[i]).array() - first;
    return garment;
  }
  check_input_file(spec, "a garment mesh (.obj, .glb or .gltf)");
  const std::string e = std::filesystem::path(spec).extension().string();
  if (e == ".obj" || e == ".OBJ") return read_obj(spec);
  AMT_CHECK(e == ".glb" || e == ".gltf" || e == ".GLB" || e == ".GLTF", "--garment ", spec,
            ": expected an .obj, .glb or .gltf file or generated:KIND, found the extension '", e, "'");
  // The displayed mesh at rest (a skinned garment's bind pose, a still mesh as it is).
  const GltfVertexAnimation still = gltf_vertex_animation(read_gltf(spec), "", 30.0f);
  TriMesh garment;
  garment.V = still.frames.at(0);
  garment.F = still.faces;
  return garment;
}

std::string output_kind(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  for (char& ch : e) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  AMT_CHECK(e == ".obj" || e == ".glb" || e == ".gltf", "--out ", path,
            ": expected an .obj (the garment) or .glb/.gltf (the dressed target avatar) file, found the extension '", e,
            "'");
  return e;
}

// The avatar with the garment after it as one mesh, and the garment mask.
TriMesh dressed_mesh(const TriMesh& avatar, const MatrixX3f& garment, const MatrixX3i& garment_F,
                     std::vector<uint8_t>* mask) {
  TriMesh m;
  m.V.resize(avatar.num_vertices() + garment.rows(), 3);
  m.V << avatar.V, garment;
  m.F.resize(avatar.num_faces() + garment_F.rows(), 3);
  m.F << avatar.F, garment_F.array() + avatar.num_vertices();
  mask->assign(size_t(avatar.num_vertices()), 0);
  mask->resize(size_t(m.num_vertices()), 1);
  return m;
}

void run(const RefitCommandOptions& o) {
  const std::string kind = output_kind(o.out);
  check_replaceable_file(o.out);
  if (!o.picture.empty()) check_replaceable_file(o.picture);
  const std::vector<RunInput> inputs = {{o.garment, "--garment"},
                                        {o.source.spec, "--source"},
                                        {o.source.joints, "--source-joints"},
                                        {o.source.joint_map, "--source-joint-map"},
                                        {o.target.spec, "--target"},
                                        {o.target.joints, "--target-joints"},
                                        {o.target.joint_map, "--target-joint-map"}};
  check_output_not_input(o.out, "--out", inputs);
  check_output_not_input(o.picture, "--picture", inputs);
  const Avatar source = load_avatar(o.source, "--source");
  const Avatar target = load_avatar(o.target, "--target");
  const TriMesh garment = load_garment(o.garment, source, o.garment_share);
  AMT_CHECK(source.skeleton.parents == target.skeleton.parents, "--target ", o.target.spec,
            ": skeleton: its canonical joints' parents differ from the source's, expected the same skeleton");
  if (!o.quiet)
    std::cerr << "garment " << o.garment << ": " << garment.num_vertices() << " vertices, " << garment.num_faces()
              << " faces\nsource " << source.name << ": " << source.mesh.num_vertices() << " vertices\ntarget "
              << target.name << ": " << target.mesh.num_vertices() << " vertices, " << source.skeleton.num_joints()
              << " joints\n";
  const refit::RiggedMesh src{to_double(source.mesh.V), source.mesh.F, to_double(source.skeleton.rest_joints)};
  const refit::RiggedMesh tgt{to_double(target.mesh.V), target.mesh.F, to_double(target.skeleton.rest_joints)};
  const auto start = std::chrono::steady_clock::now();
  const refit::GarmentRefitResult r = refit::refit_garment(
      to_double(garment.V), garment.F, src, tgt, source.skeleton.parents, o.refit,
      [&](const refit::GarmentRefitProgress& p) {
        if (o.quiet) return;
        char line[200];
        std::snprintf(line, sizeof(line), "%s %d: energy %.6g, min distance %.3f mm, t %.4f", p.stage.c_str(),
                      p.iteration, p.energy, 1e3 * p.min_distance, p.t);
        std::cerr << line;
        if (p.stage == "inflation") std::cerr << ", " << p.newton_iterations << " Newton iterations";
        std::cerr << "\n";
      },
      "--garment " + o.garment, "--source " + o.source.spec, "--target " + o.target.spec);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const MatrixX3f fitted = r.garment.cast<float>();
  if (kind == ".obj") {
    write_obj(o.out, TriMesh{fitted, garment.F});
  } else {
    std::vector<uint8_t> mask;
    const TriMesh dressed = dressed_mesh(target.mesh, fitted, garment.F, &mask);
    const SparseWeights garment_weights = refit::transfer_weights(r.garment, tgt.V, target.weights);
    SparseWeights weights;
    weights.indices.resize(dressed.num_vertices(), kMaxInfluences);
    weights.weights.resize(dressed.num_vertices(), kMaxInfluences);
    weights.indices << target.weights.indices, garment_weights.indices;
    weights.weights << target.weights.weights, garment_weights.weights;
    GltfExportOptions export_options;
    export_options.name = target.name + "_dressed";
    export_options.clip = "rest";
    export_gltf_rigged(o.out, dressed, target.skeleton, weights, rest_motion(target.skeleton, 1), export_options);
  }
  if (!o.picture.empty()) {
    // Before (the garment on the source avatar) and after, at one scale so that the heights compare.
    std::vector<uint8_t> before_mask, after_mask;
    const TriMesh before = dressed_mesh(source.mesh, garment.V, garment.F, &before_mask);
    const TriMesh after = dressed_mesh(target.mesh, fitted, garment.F, &after_mask);
    RenderOptions view;
    view.width = 420;
    view.height = 480;
    view.world_height = 1.08f * std::max(before.V.col(1).maxCoeff(), after.V.col(1).maxCoeff());
    write_png(image_grid({render_character(before, before_mask, view), render_character(after, after_mask, view)}, 2),
              o.picture);
  }
  char summary[600];
  std::snprintf(summary, sizeof(summary),
                "refit %s onto %s in %.1f s (shrink %.1f s, inflation %.1f s in %d outer iterations, fit %.1f s in %d "
                "Newton iterations: %s)\n"
                "  surface-shape distortion |tau1 x - tau2 x|: RMS %.4f, max %.4f over adjacent face pairs\n"
                "  fit distance (mean |D| over the %d fitted vertices): %.2f mm on the source, %.2f mm on the target\n"
                "  min distance garment-garment / garment-avatar: %.3f mm; crossing triangle pairs: %d\n"
                "wrote %s\n",
                o.garment.c_str(), o.target.spec.c_str(), seconds, r.shrink_seconds, r.inflation_seconds,
                r.outer_iterations, r.fit_seconds, r.fit_iterations, r.fit_stop_reason.c_str(), r.distortion_rms,
                r.distortion_max, r.fit_vertices, 1e3 * r.source_fit_distance, 1e3 * r.fit_distance,
                1e3 * r.min_distance, r.crossing_pairs, o.out.c_str());
  std::cout << summary << std::flush;
}

}  // namespace

void add_refit_garment_command(CLI::App& app) {
  auto o = std::make_shared<RefitCommandOptions>();
  refit::GarmentRefitOptions& r = o->refit;
  auto* cmd = app.add_subcommand(
      "refit-garment",
      "Move a garment designed on a source avatar onto a target avatar of other proportions, free of "
      "intersections (skeleton shrink, inflation, garment fit with an IPC barrier and CCD-filtered Newton)");
  cmd->footer(
      "The target avatar is shrunk onto its skeleton, placed on the source skeleton inside the garment and\n"
      "inflated back to its shape while the garment keeps its shape and makes room (augmented Lagrangian on t);\n"
      "then the garment is fitted onto it (fit term on the avatar's signed distance field). No step passes\n"
      "through anything (continuous collision detection). Defaults are the paper's weights; metres.\n"
      "Both avatars need skeletons that map onto amt's 22 canonical joints. The garment must not cross itself\n"
      "or the source avatar.\n"
      "Example (generated bodies, the builder's flared skirt):\n"
      "  amt refit-garment --garment generated:flared_skirt --source generated:3 --target generated:11 \\\n"
      "      --out dressed.glb --picture refit.png");
  cmd->add_option("--garment", o->garment,
                  "Garment: .obj, .glb/.gltf (the displayed mesh at rest), or generated:KIND[:SEED], the dataset "
                  "builder's apparel piece of that kind (flared_skirt, pleated_skirt, sleeves, cape, ...) dressed "
                  "onto a generated source avatar")
      ->required();
  cmd->add_option("--garment-share", o->garment_share,
                  "A generated garment's share of the dressed source's vertices (its resolution)")
      ->check(CLI::Range(0.05, 0.8))
      ->capture_default_str();
  cmd->add_option("--source", o->source.spec,
                  "Avatar the garment was made for: .glb/.gltf (rigged), .obj (+ <name>.joints.json), .pmx, or "
                  "generated:SEED[:VERTICES] (a generated body without apparel, 3000 vertices by default)")
      ->required();
  cmd->add_option("--target", o->target.spec, "Avatar to dress, as --source")->required();
  cmd->add_option("--source-joints", o->source.joints, "Joints JSON giving the skeleton of an unrigged source mesh");
  cmd->add_option("--target-joints", o->target.joints, "Joints JSON giving the skeleton of an unrigged target mesh");
  cmd->add_option("--source-joint-map", o->source.joint_map, "JSON map {canonical joint: source joint}");
  cmd->add_option("--target-joint-map", o->target.joint_map, "JSON map {canonical joint: target joint}");
  cmd->add_option("--out", o->out,
                  "Output: .obj (the fitted garment) or .glb/.gltf (the target avatar dressed with it, rigged on the "
                  "canonical skeleton, the garment skinned like its nearest avatar vertex: amt animate animates it)")
      ->required();
  cmd->add_option("--picture", o->picture, "Also write a PNG: the garment on the source avatar, then on the target");
  cmd->add_option("--fit", r.weights.fit_weight, "w_fit: weight of the fit term (0: no fit term)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--positional", r.weights.positional_weight, "w_pos: weight of the boundary positional term")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--surface", r.weights.surface_weight, "Weight of the surface-shape term")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--curve", r.weights.curve_weight, "Weight of the curve-shape term (boundary loops)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--contact", r.weights.contact_weight, "w_contact: stiffness of the contact barrier")
      ->check(CLI::Range(1e-9, 1e12))
      ->capture_default_str();
  cmd->add_option("--d-hat", r.weights.d_hat, "Barrier activation distance, metres (the paper's 0.002)")
      ->check(CLI::Range(1e-5, 0.05))
      ->capture_default_str();
  cmd->add_option("--fit-region", r.fit_region_distance,
                  "Garment vertices within this distance of the source avatar are fitted (metres; 0: none)")
      ->check(CLI::Range(0.0, 0.5))
      ->capture_default_str();
  cmd->add_option("--voxel-size", r.voxel_size, "Voxel size of the avatars' signed distance fields, metres")
      ->check(CLI::Range(0.0005, 0.05))
      ->capture_default_str();
  cmd->add_option("--max-outer", r.max_outer_iterations, "Outer iterations of the inflation before giving up")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--max-newton", r.newton.max_iterations, "Newton iterations per solve")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_flag("--quiet", o->quiet, "No input and progress lines on stderr");
  add_threads_option(*cmd);
  cmd->callback([o] {
    RefitCommandOptions options = *o;
    options.refit.field_band = std::max(options.refit.field_band, 10 * options.refit.voxel_size);
    run(options);
  });
}

}  // namespace amt::app
