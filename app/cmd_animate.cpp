// `amt animate`: a character and a motion -> an animated GLB, an OBJ folder or a dataset file
// (infer/runtime_torch.h). Prints the joint mappings, a progress line and a summary.
#include <cctype>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "app/commands.h"
#include "app/repository.h"
#include "data_tools/geometry/error.h"
#include "infer/runtime_torch.h"

namespace amt::app {

// The model of `amt animate` when --model is not given: the shipped one.
constexpr const char* kDefaultModel = "models/pretrained";

std::string strain_floor_text() {
  std::ostringstream text;
  text << kDefaultStrainFloor;
  return text.str();
}

void add_animate_command(CLI::App& app) {
  auto o = std::make_shared<AnimateOptions>();
  auto fps = std::make_shared<double>(0.0);
  auto bvh_scale = std::make_shared<double>(0.0);
  auto no_resolve = std::make_shared<bool>(false);
  auto quiet = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand("animate", "Animate a character with a motion: apparel dynamics on the CPU");
  cmd->add_option("--character", o->character.spec,
                  "Character: .glb/.gltf (rigged), .vrm (VRM 0.x / 1.0 avatar: its humanoid map and spring bones are "
                  "used), .obj (+ <name>.joints.json), .pmx, data.h5:character, or "
                  "generated:SEED[:VERTICES]")
      ->required();
  cmd->add_option("--motion", o->motion.spec,
                  "Motion: .bvh, .glb/.gltf animation, .vmd (MikuMikuDance, posed on the PMX model it was made for: "
                  "--motion-model, or the --character when it is a .pmx), or data.h5:clip")
      ->required();
  cmd->add_option("--motion-model", o->motion.model,
                  "The PMX model a .vmd motion was made for (default: the --character when it is a .pmx): its bones "
                  "are posed as MikuMikuDance poses them (IK, append rotations), then played on the character");
  auto* model = cmd->add_option("--model", o->model_dir,
                                "Folder of the trained checkpoints (segmenter, skinning, apparel, refiner). " +
                                    repository_default_help(kDefaultModel));
  auto* out = cmd->add_option("--out", o->out,
                              "Output: .glb (a skinned animation: the body on its joints, the apparel on handles), "
                              ".h5 (dataset format, for amt eval) or a folder of OBJ files (optional with --html)");
  cmd->add_flag("--vertex-cache", o->vertex_cache,
                "Write the .glb as a per-frame vertex cache (every vertex exactly as computed, about 20 times "
                "larger) instead of a skinned animation");
  auto* html = cmd->add_option("--html", o->html_dir,
                               "Also write a viewer folder: prediction.glb beside skinning.glb and the web page that "
                               "plays them (open it with amt view DIR)");
  cmd->add_option("--picture", o->picture, "Also write a PNG of four frames spread over the clip (a quick look)");
  cmd->add_option("--bind", o->bind_path,
                  "Bind cache file (default: <out>.bind beside the output; 'none' disables it)");
  cmd->add_option("--character-joints", o->character.joints, "Joints JSON giving the skeleton of an unrigged mesh");
  cmd->add_option("--character-joint-map", o->character.joint_map, "JSON map {canonical joint: character joint}");
  cmd->add_option("--motion-joint-map", o->motion.joint_map, "JSON map {canonical joint: motion joint}");
  cmd->add_option("--clip", o->motion.clip, "glTF animation clip name (default: the first)");
  cmd->add_option("--bvh-scale", *bvh_scale, "Metres per BVH unit (default: detected)")
      ->check(CLI::Range(1e-6, 1000.0));
  cmd->add_option("--apparel-mask", o->apparel_mask,
                  "Where the apparel mask comes from: auto (default: the character's rig when it has one, else the "
                  "segmenter; the run says which), model (the segmenter), rig (the character's own rig: "
                  "a PMX model's physics-driven vertices, a glTF's chains of bones outside the canonical skeleton, a "
                  "dataset or generated character's apparel), or a "
                  "per-vertex 0/1 mask file (JSON array or text)");
  cmd->add_option("--apparel-handles", o->apparel_handles,
                  "Where the apparel module's handles are: auto or model (default: picked automatically along the "
                  "apparel, as the module was trained; it measures better than the rig's bones), or rig (the rig's "
                  "own apparel bones: a PMX model's physics-driven bones, a glTF's chain bones, a dataset rig's "
                  "apparel bones)")
      ->check(CLI::IsMember({"auto", "rig", "model"}))
      ->capture_default_str();
  cmd->add_option("--skin-weights", o->skin_weights,
                  "Where the skinning weights come from: auto (default: the character's own skin when its file has "
                  "one, a skinned glTF / VRM or a PMX model, else the skinning predictor; the run says which), model "
                  "(the skinning predictor), or rig (the character's own skin)")
      ->check(CLI::IsMember({"auto", "rig", "model"}))
      ->capture_default_str();
  cmd->add_option("--apparel", o->apparel,
                  "What moves the apparel: learned (the apparel module, default) or physics (a PMX model's own rigid "
                  "bodies and joints, simulated under the motion as its artist tuned them, baked into the output), or "
                  "spring-bones (a VRM avatar's own spring bones, simulated as the VRM specification defines at 120 "
                  "steps per second whatever the frame rate)")
      ->check(CLI::IsMember({"learned", "physics", "spring-bones"}))
      ->capture_default_str();
  cmd->add_option("--fps", *fps, "Output frame rate (default: 30 for BVH/glTF motions, a dataset clip's own rate)")
      ->check(CLI::Range(0.001, 1000.0));
  cmd->add_option("--frames", o->playback.frames, "At most this many frames (0: all)")->check(CLI::NonNegativeNumber);
  cmd->add_option("--lead-in", o->playback.lead_in,
                  "Frames blending from the rest pose into the first frame (not written; with --apparel "
                  "spring-bones they count at 30 fps, so that the lead-in lasts as long at every frame rate)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_flag("--refiner", o->refine,
                "Also run the model's joint refiner after the apparel module (off by default: it gains at most "
                "0.01 cm on the held-out characters for about a third of the frame's time)");
  cmd->add_option("--strain-limit", o->strain_limit,
                  "Largest stretch of an apparel edge over its rest length that the learned apparel is limited to "
                  "(projections per frame until every apparel edge is within it and at least " +
                      strain_floor_text() +
                      " times its rest length; apparel vertices only, welded seams one point; 0: off)")
      ->check(CLI::Number & (CLI::IsMember({0.0f}) | CLI::Range(1.01f, 100.0f)))
      ->capture_default_str();
  cmd->add_option("--swing-calibration", o->swing_calibration,
                  "auto: scale the learned apparel's swing, per piece, to the character's own physics when it has "
                  "some (a PMX model's rigid bodies, a VRM avatar's spring bones: fitted over the model folder's "
                  "calibration_motion*.bvh; a dataset's rig: its probe response); off: the apparel module as trained")
      ->check(CLI::IsMember({"auto", "off"}))
      ->capture_default_str();
  cmd->add_flag("--no-resolve-penetration", *no_resolve, "Do not push apparel out of the body");
  cmd->add_flag_callback(
      "--push-rest-penetration", [o] { o->penetration.keep_rest_penetration = false; },
      "Also push out apparel that is inside the body at rest (by default it stays where the model has it: hair "
      "roots in the scalp, a hem under a collar)");
  cmd->add_option("--penetration-margin", o->penetration.margin,
                  "Distance outside the body a pushed vertex ends at, metres")
      ->check(CLI::Range(0.0, 0.1))
      ->capture_default_str();
  cmd->add_flag("--quiet", *quiet, "No mapping and progress lines on stderr");
  add_threads_option(*cmd);
  cmd->callback([o, model, out, html, fps, bvh_scale, no_resolve, quiet] {
    AnimateOptions options = *o;
    AMT_CHECK(out->count() > 0 || html->count() > 0, "--out: expected an output (or --html DIR), found none");
    if (html->count() > 0) {
      options.viewer_dir = find_repository_folder("viewer");
      AMT_CHECK(!options.viewer_dir.empty(),
                "--html: expected the repository's viewer/ folder above the amt program "
                "or in the current folder, found none: run amt from a checkout");
    }
    if (model->count() == 0 && options.apparel != "physics" && options.apparel != "spring-bones")
      options.model_dir = repository_default(kDefaultModel, "--model", "FOLDER (trained model)");
    if (*fps > 0) options.playback.fps = float(*fps);
    if (*bvh_scale > 0) options.motion.bvh_scale = *bvh_scale;
    // A VMD motion without --motion-model is taken as made for the character: a PMX character's file (and its
    // joint map) poses it.
    const auto lower_extension = [](const std::string& path) {
      std::string e = std::filesystem::path(path).extension().string();
      for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
      return e;
    };
    if (options.motion.model.empty() && lower_extension(options.motion.spec) == ".vmd" &&
        lower_extension(options.character.spec) == ".pmx") {
      options.motion.model = options.character.spec;
      if (options.motion.joint_map.empty()) options.motion.joint_map = options.character.joint_map;
    }
    options.resolve_penetration = !*no_resolve;
    options.verbose = !*quiet;
    const AnimateSummary summary = animate(options);
    std::cout << describe(summary) << std::flush;
  });
}

}  // namespace amt::app
