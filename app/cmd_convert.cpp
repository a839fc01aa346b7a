// `amt convert MODEL.pmx --out OUT.glb|OUT.vrm`: a MikuMikuDance model as glTF 2.0 or as a VRM 1.0 avatar, its
// physics as spring bones (data_tools/formats/pmx_gltf.h). Prints what was written and what was left out.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "app/commands.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/joint_map.h"
#include "data_tools/formats/pmx_gltf.h"
#include "data_tools/formats/pmx_import.h"
#include "data_tools/geometry/error.h"

namespace amt::app {

namespace {

struct ConvertOptions {
  std::string model, out, joint_map;
  float metres_per_unit = kPmxMetresPerUnit;
};

std::string size_text(uint64_t bytes) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(1);
  if (bytes >= (uint64_t(1) << 20)) {
    text << double(bytes) / double(1 << 20) << " MiB";
  } else {
    text << double(bytes) / 1024.0 << " KiB";
  }
  return text.str();
}

void run(const ConvertOptions& o) {
  std::string extension = std::filesystem::path(o.out).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  AMT_CHECK(extension == ".glb" || extension == ".vrm", o.out,
            ": --out: expected a file name ending in .glb (glTF) or .vrm (VRM 1.0), found ",
            extension.empty() ? std::string("none") : "'" + extension + "'");
  AMT_CHECK(std::isfinite(o.metres_per_unit) && o.metres_per_unit > 0,
            "convert: --metres-per-unit: expected a number > 0, found ", o.metres_per_unit);
  check_output_not_input(o.out, "--out", {{o.model, "MODEL"}, {o.joint_map, "--joint-map"}});
  check_replaceable_file(o.out);
  check_writable_location(o.out, "--out");
  const PmxModel model = read_pmx(o.model);
  PmxGltfOptions options;
  options.kind = extension == ".vrm" ? PmxGltfKind::kVrm : PmxGltfKind::kGlb;
  options.metres_per_unit = o.metres_per_unit;
  if (!o.joint_map.empty()) options.joint_map = read_joint_map(o.joint_map);
  const PmxGltfSummary s = write_pmx_gltf(model, o.out, options);

  std::cout << "wrote " << o.out << " (" << (options.kind == PmxGltfKind::kVrm ? "VRM 1.0" : "glTF 2.0") << ", "
            << size_text(s.bytes) << "): " << s.vertices << " vertices (" << s.pmx_vertices << " in the PMX), "
            << s.faces << " faces in " << s.primitives << " primitives, " << s.bones << " bones, " << s.materials
            << " materials, textures " << s.textures_embedded << " embedded / " << s.textures_left_out << " left out\n";
  std::cout << "spring bones: " << s.springs << " springs with " << s.spring_joints << " joints (" << s.spring_segments
            << " turning), " << s.colliders << " colliders in " << s.collider_groups << " groups\n";
  if (!s.humanoid.empty()) {
    std::cout << "humanoid:";
    for (size_t k = 0; k < s.humanoid.size(); ++k)
      std::cout << (k ? ", " : " ") << s.humanoid[k].first << "=" << s.humanoid[k].second;
    std::cout << "\n";
  }
  for (const std::string& note : s.notes) std::cout << "note: " << note << "\n";
}

}  // namespace

void add_convert_command(CLI::App& app) {
  auto o = std::make_shared<ConvertOptions>();
  auto* cmd = app.add_subcommand(
      "convert",
      "Convert a PMX model (MikuMikuDance) to glTF (.glb) or a VRM 1.0 avatar (.vrm), its physics as spring "
      "bones (VRMC_springBone)");
  cmd->footer(
      "The mesh (a primitive per material), every bone as a node of one skin, the materials with their PNG or JPEG\n"
      "textures embedded, and the rigid bodies as spring bones: chains of physics-driven bones become springs,\n"
      "bodies that follow their bones become colliders. A .vrm adds the VRM 1.0 humanoid (from MMD's bone names)\n"
      "and meta with the most restrictive permissions. Morphs, sphere and toon textures are dropped.\n"
      "docs/characters.md, \"Converting a PMX model to glTF or VRM\", has the details and limits.\n"
      "Example:\n"
      "  amt dataset export-pmx --seed 1 --character 0 --out out/c0/c0.pmx\n"
      "  amt convert out/c0/c0.pmx --out out/c0.vrm");
  cmd->add_option("MODEL", o->model, "PMX model (.pmx); its textures are read from its folder")->required();
  cmd->add_option("--out", o->out, "Output .glb or .vrm (written to a temporary name, then renamed)")->required();
  cmd->add_option("--joint-map", o->joint_map,
                  "JSON map {canonical joint: bone} for a .vrm's humanoid when the bones do not have MMD's standard "
                  "names");
  cmd->add_option("--metres-per-unit", o->metres_per_unit, "Metres per PMX unit")->capture_default_str();
  add_threads_option(*cmd);
  cmd->callback([o] { run(*o); });
}

}  // namespace amt::app
