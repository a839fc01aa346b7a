// `amt retarget-cloth`: the apparel motion of a source character carried onto a target character with the same
// apparel connectivity (infer/retarget_cloth.h, the cloth-retargeting paper). Prints the inputs, a progress line
// and a summary.
#include <iostream>
#include <memory>

#include "app/commands.h"
#include "infer/retarget_cloth.h"

namespace amt::app {

void add_retarget_cloth_command(CLI::App& app) {
  auto o = std::make_shared<RetargetClothOptions>();
  auto bvh_scale = std::make_shared<double>(0.0);
  auto no_resolve = std::make_shared<bool>(false);
  auto no_shorten = std::make_shared<bool>(false);
  auto no_scale = std::make_shared<bool>(false);
  auto quiet = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "retarget-cloth",
      "Carry the apparel motion of a source character onto a target character whose apparel has the same "
      "connectivity (cloth motion retargeting: body-oriented apparel + detail vectors, collisions resolved)");
  cmd->footer(
      "Per frame: the source apparel's detail vectors (source apparel minus its body-oriented version, the\n"
      "rest apparel wrapped onto the moving source body), scaled by the apparel's size on the target over the\n"
      "source, are added to the body-oriented target apparel; detail vectors reaching deeper towards the body\n"
      "than the apparel's clearance are shortened, the apparel's edges are relaxed towards their rest lengths,\n"
      "and apparel vertices left inside the target body (winding number) are pushed out along the body's\n"
      "normal by their depth.\n"
      "Example (a pair set from `amt dataset pairs --out pairs.h5`):\n"
      "  amt retarget-cloth --source pairs.h5:pair-00-a__proc-walk-000 --target pairs.h5:pair-00-b --out b.glb");
  cmd->add_option("--source", o->source,
                  "Source apparel motion: a dataset clip data.h5:clip (its character's simulation), or a folder of "
                  "OBJ frames frame_0000.obj, ... (whole meshes, body and apparel) with --source-character")
      ->required();
  cmd->add_option("--source-character", o->source_character,
                  "Rest character of an OBJ source (data.h5:character: rest mesh and apparel mask)");
  cmd->add_option("--target", o->target,
                  "Target character data.h5:character; its apparel must have the source's connectivity")
      ->required();
  cmd->add_option("--target-motion", o->target_motion.spec,
                  "Target body motion: .bvh, .glb/.gltf animation or data.h5:clip (default: the source clip's motion, "
                  "retargeted onto the target)");
  cmd->add_option("--motion-joint-map", o->target_motion.joint_map, "JSON map {canonical joint: motion joint}");
  cmd->add_option("--clip", o->target_motion.clip, "glTF animation clip name of the target motion (default: the first)");
  cmd->add_option("--bvh-scale", *bvh_scale, "Metres per BVH unit (default: detected)")->check(CLI::Range(1e-6, 1000.0));
  cmd->add_option("--out", o->out,
                  "Output: .glb (animated mesh), .h5 (dataset format, for amt eval --predictions) or a folder of OBJ "
                  "files")
      ->required();
  cmd->add_option("--frames", o->frames, "At most this many frames (0: all of the target motion)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--fps", o->fps, "Frame rate of an OBJ source")->check(CLI::Range(0.001, 1000.0))->capture_default_str();
  cmd->add_option("--wrap-faces", o->retarget.wrap.faces, "Body faces each apparel vertex is registered to")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  cmd->add_option("--detail-clearance", o->retarget.detail_clearance,
                  "Longest inward part of a detail vector, as a share of the apparel's clearance above the body")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  cmd->add_flag("--no-scale-details", *no_scale,
                "Add the detail vectors unchanged (default: scaled per vertex by the target apparel's size over the source's)");
  cmd->add_option("--relax-iterations", o->retarget.relax_iterations,
                  "Iterations pulling the retargeted apparel's edges towards their rest lengths (0: none)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_flag("--no-shorten", *no_shorten, "Keep the detail vectors whole (no section 3.1 shortening)");
  cmd->add_flag("--no-resolve-penetration", *no_resolve, "Do not push apparel out of the target body (measure only)");
  cmd->add_option("--penetration-margin", o->retarget.penetration.margin,
                  "Distance outside the body a pushed vertex ends at, metres")
      ->check(CLI::Range(0.0, 0.1))
      ->capture_default_str();
  cmd->add_flag("--quiet", *quiet, "No input and progress lines on stderr");
  add_threads_option(*cmd);
  cmd->callback([o, bvh_scale, no_resolve, no_shorten, no_scale, quiet] {
    RetargetClothOptions options = *o;
    if (*bvh_scale > 0) options.target_motion.bvh_scale = *bvh_scale;
    if (*no_shorten) options.retarget.detail_clearance = 0;
    options.retarget.scale_details = !*no_scale;
    options.retarget.resolve = !*no_resolve;
    options.verbose = !*quiet;
    std::cout << describe(retarget_cloth(options)) << std::flush;
  });
}

}  // namespace amt::app
