#include "data_tools/formats/gltf_export.h"

// tinygltf is Debian's libtinygltf (linked by data_tools/formats/CMakeLists.txt), built with its default
// options: no TINYGLTF_* option macros may be defined before including it.
#include <tiny_gltf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "amt/version.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/gltf_buffer.h"
#include "data_tools/geometry/error.h"

namespace amt {

namespace {

// Largest frame count of a mesh sequence: the sparse weights accessor holds T (T - 1) elements,
// addressed by UNSIGNED_INT indices.
constexpr size_t kMaxSequenceFrames = 65536;

// Builds a tinygltf model with one buffer; every buffer view starts on a 4-byte boundary.
class ModelBuilder {
 public:
  ModelBuilder() : buffer_(model_) {
    model_.asset.version = "2.0";
    model_.asset.generator = std::string("amt ") + AMT_VERSION;
  }

  tinygltf::Model& model() { return model_; }

  /// Appends bytes as a new buffer view (target 0 for none); returns its index.
  int add_view(const void* bytes, size_t size, int target) { return buffer_.view(bytes, size, target); }

  /// Adds a FLOAT accessor over `values` (count x components, row-major) in a view of its own; with
  /// `bounds`, min and max per component (required for POSITION and animation inputs).
  int add_floats(const std::vector<float>& values, int type, int components, int target, bool bounds) {
    return buffer_.accessor(values, TINYGLTF_COMPONENT_TYPE_FLOAT, type, components, target, bounds);
  }

  /// Adds an integer accessor (UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT components) over
  /// `values` (count x components) in a view of its own.
  int add_integers(const std::vector<uint32_t>& values, int component_type, int type, int components, int target) {
    std::vector<unsigned char> bytes;
    const size_t size = component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                        : component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                                                                                   : 4;
    bytes.resize(values.size() * size);
    for (size_t i = 0; i < values.size(); ++i) {
      if (size == 1) {
        bytes[i] = static_cast<unsigned char>(values[i]);
      } else if (size == 2) {
        const auto v = static_cast<uint16_t>(values[i]);
        std::memcpy(&bytes[2 * i], &v, 2);
      } else {
        std::memcpy(&bytes[4 * i], &values[i], 4);
      }
    }
    tinygltf::Accessor acc;
    acc.bufferView = add_view(bytes.data(), bytes.size(), target);
    acc.componentType = component_type;
    acc.type = type;
    acc.count = values.size() / size_t(components);
    model_.accessors.push_back(acc);
    return int(model_.accessors.size()) - 1;
  }

  /// Adds a normalized integer VEC4 accessor over `bytes` (count elements of component type `component_type`:
  /// UNSIGNED_BYTE or UNSIGNED_SHORT) in a view of its own; returns its index.
  int add_normalized_vec4(const void* bytes, size_t size, size_t count, int component_type, int target) {
    tinygltf::Accessor acc;
    acc.bufferView = add_view(bytes, size, target);
    acc.componentType = component_type;
    acc.normalized = true;
    acc.type = TINYGLTF_TYPE_VEC4;
    acc.count = count;
    model_.accessors.push_back(acc);
    return int(model_.accessors.size()) - 1;
  }

  /// Adds an animation sampler (LINEAR) and its channel to `animation`.
  static void add_channel(tinygltf::Animation& animation, int input, int output, int node, const char* path) {
    tinygltf::AnimationSampler sampler;
    sampler.input = input;
    sampler.output = output;
    sampler.interpolation = "LINEAR";
    animation.samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = int(animation.samplers.size()) - 1;
    channel.target_node = node;
    channel.target_path = path;
    animation.channels.push_back(channel);
  }

  /// Sets asset.extras to amt's format record.
  void set_format(const char* format, float fps) {
    tinygltf::Value::Object extras;
    extras["amt_format"] = tinygltf::Value(std::string(format));
    extras["amt_format_version"] = tinygltf::Value(1);
    extras["fps"] = tinygltf::Value(double(fps));
    model_.asset.extras = tinygltf::Value(extras);
  }

  /// Adds the apparel tint's record to asset.extras (after set_format).
  void set_apparel_record(int apparel_vertices) {
    tinygltf::Value::Object extras = model_.asset.extras.Get<tinygltf::Value::Object>();
    extras["apparel_color"] = tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(int(kApparelColor[0])),
                                                                     tinygltf::Value(int(kApparelColor[1])),
                                                                     tinygltf::Value(int(kApparelColor[2]))});
    extras["apparel_vertices"] = tinygltf::Value(apparel_vertices);
    model_.asset.extras = tinygltf::Value(extras);
  }

 private:
  tinygltf::Model model_;
  GltfBuffer buffer_;
};

// Keyframe times k / fps for k = 0 .. T - 1.
std::vector<float> keyframe_times(int frames, float fps) {
  std::vector<float> times(static_cast<size_t>(frames));
  for (int k = 0; k < frames; ++k) times[size_t(k)] = float(double(k) / double(fps));
  return times;
}

// Triangle indices as the smallest unsigned type that holds every vertex index.
int add_indices(ModelBuilder& builder, const MatrixX3i& F, int num_vertices) {
  std::vector<uint32_t> indices(size_t(F.size()));
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) indices[size_t(f) * 3 + size_t(k)] = uint32_t(F(f, k));
  }
  const int type =
      num_vertices <= 65535 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  return builder.add_integers(indices, type, TINYGLTF_TYPE_SCALAR, 1, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
}

std::vector<float> rows_to_floats(const MatrixX3f& V) {
  return std::vector<float>(V.data(), V.data() + V.size());  // row-major: x y z per vertex
}

GltfContainer container_for(const std::string& path, const GltfExportOptions& options) {
  if (options.container) return *options.container;
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".gltf" ? GltfContainer::kEmbeddedGltf : GltfContainer::kGlb;
}

// Serialises the model and writes it to "<path>.amt-tmp", then renames it onto path.
void write_model(const std::string& path, ModelBuilder& builder, GltfContainer container) {
  tinygltf::Model& model = builder.model();
  const size_t bytes = model.buffers[0].data.size();
  AMT_CHECK(container == GltfContainer::kEmbeddedGltf || bytes < (size_t(1) << 32) - (size_t(1) << 24), path,
            ": buffer: expected less than 4 GiB of data for a GLB file, found ", bytes, " bytes");
  std::ostringstream stream;
  tinygltf::TinyGLTF writer;
  const bool binary = container == GltfContainer::kGlb;
  AMT_CHECK(writer.WriteGltfSceneToStream(&model, stream, false, binary), path,
            ": write: expected tinygltf to serialise the model, found an error");
  const std::string content = stream.str();
  write_file_atomically(path, content);
}

void check_fps(float fps, const std::string& path) {
  AMT_CHECK(std::isfinite(fps) && fps > 0.0f, path, ": fps: expected a positive frame rate, found ", fps);
}

// The COLOR_0 tint of `mask` (#V entries 0/1) on `primitive`, and its record in asset.extras.
void add_apparel_tint(ModelBuilder& builder, tinygltf::Primitive& primitive, const std::vector<uint8_t>& mask,
                      int num_vertices, const std::string& path) {
  if (mask.empty()) return;
  AMT_CHECK(mask.size() == size_t(num_vertices), path, ": apparel mask: expected ", num_vertices, " entries, found ",
            mask.size());
  const std::vector<uint8_t> colors = apparel_vertex_colors(mask, path);
  primitive.attributes["COLOR_0"] =
      builder.add_normalized_vec4(colors.data(), colors.size(), size_t(num_vertices),
                                  TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TARGET_ARRAY_BUFFER);
  builder.set_apparel_record(int(std::count(mask.begin(), mask.end(), 1)));
}

}  // namespace

// === Mesh sequence

std::vector<uint8_t> apparel_vertex_colors(const std::vector<uint8_t>& apparel_mask, const std::string& path) {
  std::vector<uint8_t> colors(apparel_mask.size() * 4);
  for (size_t i = 0; i < apparel_mask.size(); ++i) {
    AMT_CHECK(apparel_mask[i] <= 1, path, ": apparel mask: expected 0 or 1, found ", int(apparel_mask[i]),
              " at vertex ", i);
    std::memcpy(&colors[4 * i], apparel_mask[i] ? kApparelColor : kBodyColor, 4);
  }
  return colors;
}

void export_gltf_mesh_sequence(const std::string& path, const MatrixX3i& F, const std::vector<MatrixX3f>& frames,
                               float fps, const GltfExportOptions& options) {
  check_fps(fps, path);
  AMT_CHECK(!frames.empty(), path, ": frames: expected at least 1 frame, found none");
  AMT_CHECK(frames.size() <= kMaxSequenceFrames, path, ": frames: expected at most ", kMaxSequenceFrames,
            " frames, found ", frames.size());
  const TriMesh first{frames[0], F};
  validate_mesh(first, path + ": frame 0");
  const int N = first.num_vertices();
  for (size_t k = 1; k < frames.size(); ++k) {
    AMT_CHECK(frames[k].rows() == N, path, ": frames: expected ", N, " vertices in every frame, found ",
              frames[k].rows(), " in frame ", k);
    AMT_CHECK(frames[k].allFinite(), path, ": frames: expected finite positions, found NaN or infinity in frame ", k);
  }
  const int T = int(frames.size());

  ModelBuilder builder;
  builder.set_format("mesh-sequence", fps);
  tinygltf::Model& model = builder.model();
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.attributes["POSITION"] =
      builder.add_floats(rows_to_floats(frames[0]), TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
  primitive.indices = add_indices(builder, F, N);
  add_apparel_tint(builder, primitive, options.apparel_mask, N, path);
  tinygltf::Mesh mesh;
  mesh.name = options.name;
  tinygltf::Value::Array target_names;
  for (int k = 1; k < T; ++k) {
    const MatrixX3f delta = frames[size_t(k)] - frames[0];
    std::map<std::string, int> target;
    target["POSITION"] =
        builder.add_floats(rows_to_floats(delta), TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
    primitive.targets.push_back(target);
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%04d", k);
    target_names.emplace_back(std::string(name));
  }
  mesh.primitives.push_back(primitive);
  if (T > 1) {
    mesh.weights.assign(size_t(T - 1), 0.0);
    tinygltf::Value::Object extras;
    extras["targetNames"] = tinygltf::Value(target_names);
    mesh.extras = tinygltf::Value(extras);
  }
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.name = options.name;
  node.mesh = 0;
  model.nodes.push_back(node);

  if (T > 1) {
    // Weights output: T keys x (T - 1) targets, zero but for target k - 1 = 1 at key k (sparse).
    const size_t targets = size_t(T - 1);
    std::vector<uint32_t> indices;
    std::vector<float> ones;
    for (size_t k = 1; k < size_t(T); ++k) {
      indices.push_back(uint32_t(k * targets + (k - 1)));
      ones.push_back(1.0f);
    }
    tinygltf::Accessor weights;
    weights.bufferView = -1;
    weights.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    weights.type = TINYGLTF_TYPE_SCALAR;
    weights.count = size_t(T) * targets;
    weights.sparse.isSparse = true;
    weights.sparse.count = int(indices.size());
    weights.sparse.indices.bufferView = builder.add_view(indices.data(), indices.size() * sizeof(uint32_t), 0);
    weights.sparse.indices.byteOffset = 0;
    weights.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    weights.sparse.values.bufferView = builder.add_view(ones.data(), ones.size() * sizeof(float), 0);
    weights.sparse.values.byteOffset = 0;
    model.accessors.push_back(weights);
    const int output = int(model.accessors.size()) - 1;
    const int input = builder.add_floats(keyframe_times(T, fps), TINYGLTF_TYPE_SCALAR, 1, 0, true);
    tinygltf::Animation animation;
    animation.name = options.clip;
    ModelBuilder::add_channel(animation, input, output, 0, "weights");
    model.animations.push_back(animation);
  }
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  write_model(path, builder, container_for(path, options));
}

// === Skinned characters

namespace {

// A skinned character animated by node transforms, with asset.extras.amt_format `format` (the construction at the
// top of data_tools/formats/gltf_export.h).
void write_skinned(const std::string& path, const TriMesh& mesh, const Skeleton& skeleton, const SparseWeights& weights,
                   const NodeAnimation& animation, const GltfExportOptions& options, const char* format, bool compact) {
  validate_mesh(mesh, path + ": mesh");
  validate_skeleton(skeleton, path + ": skeleton");
  check_fps(animation.fps, path);
  const int N = mesh.num_vertices(), J = skeleton.num_joints();
  const int T = animation.num_frames(J);
  AMT_CHECK(T >= 1 && animation.rotations.size() == size_t(T) * size_t(J) &&
                animation.translations.size() == animation.rotations.size() && animation.translated.size() == size_t(J),
            path, ": animation: expected T x ", J, " rotations and translations and ", J, " translation flags, found ",
            animation.rotations.size(), ", ", animation.translations.size(), " and ", animation.translated.size());
  AMT_CHECK(weights.num_vertices() == N && weights.weights.rows() == N, path, ": weights: expected ", N,
            " rows (one per vertex), found ", weights.num_vertices());
  AMT_CHECK(J <= 65536, path, ": skeleton: expected at most 65536 joints, found ", J);

  // JOINTS_0 / WEIGHTS_0: repeated joints merged, slots sorted by weight, rows renormalised, and
  // zero-weight slots at joint 0 (glTF 2.0 section 3.7.3.3).
  std::vector<uint32_t> joint_indices(size_t(N) * 4, 0);
  std::vector<float> joint_weights(size_t(N) * 4, 0.0f);
  for (int i = 0; i < N; ++i) {
    std::vector<std::pair<int, float>> slots;
    for (int s = 0; s < kMaxInfluences; ++s) {
      const int j = weights.indices(i, s);
      const float w = weights.weights(i, s);
      AMT_CHECK(std::isfinite(w) && w >= 0.0f, path, ": weights: expected finite non-negative weights, found ", w,
                " at vertex ", i);
      if (w == 0.0f) continue;
      AMT_CHECK(j >= 0 && j < J, path, ": weights: expected joint indices in [0, ", J, "), found ", j, " at vertex ",
                i);
      auto same = std::find_if(slots.begin(), slots.end(), [j](const auto& slot) { return slot.first == j; });
      if (same != slots.end()) {
        same->second += w;
      } else {
        slots.emplace_back(j, w);
      }
    }
    AMT_CHECK(!slots.empty(), path, ": weights: expected a positive weight at every vertex, found none at vertex ", i);
    std::stable_sort(slots.begin(), slots.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    float sum = 0.0f;
    for (const auto& slot : slots) sum += slot.second;
    for (size_t s = 0; s < slots.size(); ++s) {
      joint_indices[size_t(i) * 4 + s] = uint32_t(slots[s].first);
      joint_weights[size_t(i) * 4 + s] = slots[s].second / sum;
    }
  }

  // Compact weights: normalized UNSIGNED_SHORT (glTF 2.0 section 3.7.3.3), each row summing to exactly 65535 (the
  // rounding remainder on the largest slot, off by at most 1 / 65535 of a weight); a slot that rounds to 0 points
  // at joint 0, as zero-weight slots must.
  std::vector<uint16_t> packed(compact ? joint_weights.size() : 0, 0);
  for (int i = 0; compact && i < N; ++i) {
    int sum = 0;
    for (size_t k = 0; k < 4; ++k) {
      packed[size_t(i) * 4 + k] = uint16_t(std::lround(joint_weights[size_t(i) * 4 + k] * 65535.0f));
      sum += packed[size_t(i) * 4 + k];
    }
    packed[size_t(i) * 4] = uint16_t(int(packed[size_t(i) * 4]) + 65535 - sum);
    for (size_t k = 0; k < 4; ++k) {
      if (packed[size_t(i) * 4 + k] == 0) joint_indices[size_t(i) * 4 + k] = 0;
    }
  }

  ModelBuilder builder;
  builder.set_format(format, animation.fps);
  tinygltf::Model& model = builder.model();
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  primitive.attributes["POSITION"] =
      builder.add_floats(rows_to_floats(mesh.V), TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER, true);
  const int joint_type = J <= 256 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE : TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
  primitive.attributes["JOINTS_0"] =
      builder.add_integers(joint_indices, joint_type, TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER);
  if (compact) {
    primitive.attributes["WEIGHTS_0"] =
        builder.add_normalized_vec4(packed.data(), packed.size() * sizeof(uint16_t), size_t(N),
                                    TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TARGET_ARRAY_BUFFER);
  } else {
    primitive.attributes["WEIGHTS_0"] =
        builder.add_floats(joint_weights, TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  primitive.indices = add_indices(builder, mesh.F, N);
  add_apparel_tint(builder, primitive, options.apparel_mask, N, path);
  tinygltf::Mesh gltf_mesh;
  gltf_mesh.name = options.name;
  gltf_mesh.primitives.push_back(primitive);
  model.meshes.push_back(gltf_mesh);

  // Node 0: the skinned mesh; node 1 + j: joint j at its rest offset from its parent.
  tinygltf::Node mesh_node;
  mesh_node.name = options.name;
  mesh_node.mesh = 0;
  mesh_node.skin = 0;
  model.nodes.push_back(mesh_node);
  std::vector<float> inverse_binds(size_t(J) * 16, 0.0f);
  tinygltf::Skin skin;
  skin.name = "amt_skeleton";
  skin.skeleton = 1;
  std::vector<int> roots;
  for (int j = 0; j < J; ++j) {
    const int p = skeleton.parents[size_t(j)];
    const Eigen::Vector3f rest = skeleton.rest_joints.row(j).transpose();
    const Eigen::Vector3f offset = p < 0 ? rest : Eigen::Vector3f(rest - skeleton.rest_joints.row(p).transpose());
    tinygltf::Node joint;
    joint.name = skeleton.names[size_t(j)];
    joint.translation = {offset.x(), offset.y(), offset.z()};
    model.nodes.push_back(joint);
    if (p >= 0) {
      model.nodes[size_t(p) + 1].children.push_back(j + 1);
    } else {
      roots.push_back(j + 1);
    }
    skin.joints.push_back(j + 1);
    float* m = &inverse_binds[size_t(j) * 16];  // column-major translate(-J_j)
    m[0] = m[5] = m[10] = m[15] = 1.0f;
    m[12] = -rest.x(), m[13] = -rest.y(), m[14] = -rest.z();
  }
  skin.inverseBindMatrices = builder.add_floats(inverse_binds, TINYGLTF_TYPE_MAT4, 16, 0, false);
  model.skins.push_back(skin);

  tinygltf::Animation clip;
  clip.name = options.clip;
  const int input = builder.add_floats(keyframe_times(T, animation.fps), TINYGLTF_TYPE_SCALAR, 1, 0, true);
  // Every channel's keys, packed one after another: compact files keep all rotations in one buffer view and all
  // translations in another (two views instead of one per channel: less JSON).
  std::vector<unsigned char> rotation_bytes, translation_bytes;
  struct Channel {
    int joint;
    bool rotation;
    size_t offset;
  };
  std::vector<Channel> channels;
  for (int j = 0; j < J; ++j) {
    std::vector<float> rotations(size_t(T) * 4);
    for (int t = 0; t < T; ++t) {
      const Eigen::Quaternionf& q = animation.rotations[size_t(t) * size_t(J) + size_t(j)];
      AMT_CHECK(q.coeffs().allFinite() && q.norm() > 0.5f, path, ": animation: expected a unit rotation of joint ",
                skeleton.names[size_t(j)], " at frame ", t, ", found (", q.x(), ", ", q.y(), ", ", q.z(), ", ", q.w(),
                ")");
      const Eigen::Quaternionf u = q.normalized();
      float* r = &rotations[size_t(t) * 4];
      r[0] = u.x(), r[1] = u.y(), r[2] = u.z(), r[3] = u.w();
    }
    channels.push_back({j, true, rotation_bytes.size()});
    if (compact) {
      // Normalized SHORT components (glTF 2.0 section 3.11: c = round(f 32767)), half the bytes of floats; a
      // rotation is off by at most about 3e-5 rad.
      for (const float r : rotations) {
        const int16_t c = int16_t(std::lround(r * 32767.0f));
        const auto* p = reinterpret_cast<const unsigned char*>(&c);
        rotation_bytes.insert(rotation_bytes.end(), p, p + sizeof(c));
      }
    } else {
      const auto* p = reinterpret_cast<const unsigned char*>(rotations.data());
      rotation_bytes.insert(rotation_bytes.end(), p, p + rotations.size() * sizeof(float));
    }
    if (!animation.translated[size_t(j)]) continue;
    channels.push_back({j, false, translation_bytes.size()});
    for (int t = 0; t < T; ++t) {
      const Eigen::Vector3f& x = animation.translations[size_t(t) * size_t(J) + size_t(j)];
      AMT_CHECK(x.allFinite(), path, ": animation: expected a finite translation of joint ", skeleton.names[size_t(j)],
                " at frame ", t);
      const auto* p = reinterpret_cast<const unsigned char*>(x.data());
      translation_bytes.insert(translation_bytes.end(), p, p + 3 * sizeof(float));
    }
  }
  const int rotation_view = builder.add_view(rotation_bytes.data(), rotation_bytes.size(), 0);
  const int translation_view =
      translation_bytes.empty() ? -1 : builder.add_view(translation_bytes.data(), translation_bytes.size(), 0);
  for (const Channel& c : channels) {
    tinygltf::Accessor acc;
    acc.bufferView = c.rotation ? rotation_view : translation_view;
    acc.byteOffset = c.offset;
    acc.componentType = c.rotation && compact ? TINYGLTF_COMPONENT_TYPE_SHORT : TINYGLTF_COMPONENT_TYPE_FLOAT;
    acc.normalized = c.rotation && compact;
    acc.type = c.rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3;
    acc.count = size_t(T);
    model.accessors.push_back(acc);
    ModelBuilder::add_channel(clip, input, int(model.accessors.size()) - 1, c.joint + 1,
                              c.rotation ? "rotation" : "translation");
  }
  model.animations.push_back(clip);

  tinygltf::Scene scene;
  scene.nodes = {0};
  scene.nodes.insert(scene.nodes.end(), roots.begin(), roots.end());
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  write_model(path, builder, container_for(path, options));
}

}  // namespace

void append_node_frame(const Skeleton& skeleton, const Transforms& joint_transforms, NodeAnimation& animation) {
  const int J = skeleton.num_joints();
  AMT_CHECK(joint_transforms.size() == size_t(J), "append_node_frame: expected ", J, " joint transforms, found ",
            joint_transforms.size());
  for (int j = 0; j < J; ++j) {
    const int p = skeleton.parents[size_t(j)];
    const Eigen::Matrix3f R = joint_transforms[size_t(j)].leftCols<3>();
    const Eigen::Vector3f t = joint_transforms[size_t(j)].col(3);
    if (p < 0) {
      animation.rotations.emplace_back(R);
      animation.translations.push_back(t);
      continue;
    }
    const Eigen::Matrix3f Rp = joint_transforms[size_t(p)].leftCols<3>();
    const Eigen::Vector3f tp = joint_transforms[size_t(p)].col(3);
    animation.rotations.emplace_back(Eigen::Matrix3f(Rp.transpose() * R));
    animation.translations.push_back(Rp.transpose() * (t - tp));
  }
}

void export_gltf_skinned_animation(const std::string& path, const TriMesh& mesh, const Skeleton& skeleton,
                                   const SparseWeights& weights, const NodeAnimation& animation,
                                   const GltfExportOptions& options) {
  write_skinned(path, mesh, skeleton, weights, animation, options, "skinned-animation", /*compact=*/true);
}

// === Rigged character

void export_gltf_rigged(const std::string& path, const TriMesh& mesh, const Skeleton& skeleton,
                        const SparseWeights& weights, const Motion& motion, const GltfExportOptions& options) {
  validate_skeleton(skeleton, path + ": skeleton");
  validate_motion(motion, skeleton, path + ": motion");
  AMT_CHECK(motion.num_frames() >= 1, path, ": motion: expected at least 1 frame, found none");
  // The Motion's local rotations, unchanged, and the root's position J_0 + root_translation.
  const int J = skeleton.num_joints(), T = motion.num_frames();
  NodeAnimation animation;
  animation.fps = motion.fps;
  animation.translated.assign(size_t(J), 0);
  for (int j = 0; j < J; ++j) animation.translated[size_t(j)] = skeleton.parents[size_t(j)] < 0;
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < J; ++j) {
      animation.rotations.push_back(motion.rotation(t, j));
      animation.translations.push_back(skeleton.rest_joints.row(j).transpose());
      if (j == 0) {
        for (int c = 0; c < 3; ++c) animation.translations.back()(c) += motion.root_translation(t, c);
      }
    }
  }
  GltfExportOptions rigged = options;
  rigged.apparel_mask.clear();
  write_skinned(path, mesh, skeleton, weights, animation, rigged, "rigged-character", /*compact=*/false);
}

}  // namespace amt
