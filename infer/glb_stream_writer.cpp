#include "infer/glb_stream_writer.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "amt/version.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/temporary_registry.h"

namespace amt {

namespace {

constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kFloat = 5126, kUnsignedByte = 5121, kUnsignedShort = 5123, kUnsignedInt = 5125;

size_t padded4(size_t n) {
  return (n + 3) / 4 * 4;
}

void write_bytes(std::FILE* f, const void* data, size_t size, const std::string& path) {
  if (size > 0 && std::fwrite(data, 1, size, f) != size) {
    fail(path, ": write: expected to write ", size, " bytes, found an error (", std::strerror(errno), ")");
  }
}

void write_padding(std::FILE* f, size_t size, char pad, const std::string& path) {
  const size_t extra = padded4(size) - size;
  const char bytes[3] = {pad, pad, pad};
  write_bytes(f, bytes, extra, path);
}

}  // namespace

GlbStreamWriter::GlbStreamWriter(const std::string& path, const MatrixX3i& F, int num_vertices, float fps,
                                 const std::string& name, const std::string& clip,
                                 const std::vector<uint8_t>& apparel_mask)
    : path_(path),
      data_path_(frames_temporary_path(path)),
      name_(name),
      clip_(clip),
      fps_(fps),
      num_vertices_(num_vertices) {
  AMT_CHECK(std::isfinite(fps) && fps > 0, path, ": fps: expected a positive frame rate, found ", fps);
  AMT_CHECK(num_vertices > 0, path, ": vertices: expected at least 1, found ", num_vertices);
  AMT_CHECK(F.rows() > 0, path, ": faces: expected at least 1 face, found none");
  if (!apparel_mask.empty()) {
    AMT_CHECK(apparel_mask.size() == size_t(num_vertices), path, ": apparel mask: expected ", num_vertices,
              " entries, found ", apparel_mask.size());
    colors_ = apparel_vertex_colors(apparel_mask, path);
    apparel_vertices_ = int(std::count(apparel_mask.begin(), apparel_mask.end(), 1));
  }
  index_component_ = num_vertices <= 65535 ? kUnsignedShort : kUnsignedInt;
  index_count_ = size_t(F.size());
  const size_t size = index_component_ == kUnsignedShort ? 2 : 4;
  index_bytes_.resize(index_count_ * size);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int32_t v = F(f, k);
      AMT_CHECK(v >= 0 && v < num_vertices, path, ": faces: expected indices in [0, ", num_vertices, "), found ", v,
                " in face ", f);
      const size_t at = (size_t(f) * 3 + size_t(k)) * size;
      if (size == 2) {
        const auto s = uint16_t(v);
        std::memcpy(&index_bytes_[at], &s, 2);
      } else {
        const auto s = uint32_t(v);
        std::memcpy(&index_bytes_[at], &s, 4);
      }
    }
  }
  create_parent_folder(path);
  check_replaceable_file(path);
  prepare_temporary_file(data_path_);
  prepare_temporary_file(temporary_path(path));
  register_temporary(data_path_);
  data_ = std::fopen(data_path_.c_str(), "wb");
  if (data_ == nullptr) unregister_temporary(data_path_);
  AMT_CHECK(data_ != nullptr, path, ": output: expected a writable path, found an error creating ", data_path_, " (",
            std::strerror(errno), ")");
}

GlbStreamWriter::~GlbStreamWriter() {
  if (!finished_) remove_temporaries();
}

void GlbStreamWriter::remove_temporaries() {
  if (data_) std::fclose(data_), data_ = nullptr;
  discard_temporary(data_path_);
  discard_temporary(temporary_path(path_));
}

size_t GlbStreamWriter::buffered_bytes() const {
  return first_.capacity() * sizeof(float) + index_bytes_.capacity() + colors_.capacity() +
         delta_.capacity() * sizeof(float);
}

void GlbStreamWriter::append(const MatrixX3f& V) {
  AMT_CHECK(!finished_, path_, ": append: the sequence is already finished");
  AMT_CHECK(V.rows() == num_vertices_, path_, ": frame ", frames_, ": expected ", num_vertices_, " vertices, found ",
            V.rows());
  AMT_CHECK(V.allFinite(), path_, ": frame ", frames_, ": expected finite positions, found NaN or infinity");
  AMT_CHECK(frames_ < kMaxFrames, path_, ": frames: expected at most ", kMaxFrames, " frames");
  const size_t n = size_t(V.size());
  if (frames_ == 0) {
    first_.assign(V.data(), V.data() + n);
    delta_.resize(n);
  } else {
    float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                   std::numeric_limits<float>::infinity()};
    float hi[3] = {-lo[0], -lo[1], -lo[2]};
    const float* v = V.data();
    for (size_t i = 0; i < n; ++i) {
      const float d = v[i] - first_[i];
      delta_[i] = d;
      const size_t c = i % 3;
      lo[c] = std::min(lo[c], d);
      hi[c] = std::max(hi[c], d);
    }
    write_bytes(data_, delta_.data(), n * sizeof(float), data_path_);
    bounds_.insert(bounds_.end(), {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]});
  }
  ++frames_;
}

size_t GlbStreamWriter::finish() {
  AMT_CHECK(!finished_, path_, ": finish: the sequence is already finished");
  AMT_CHECK(frames_ >= 1, path_, ": frames: expected at least 1 frame, found none");
  AMT_CHECK(std::fflush(data_) == 0, data_path_, ": write: expected to flush the frame data, found an error");
  std::fclose(data_);
  data_ = nullptr;
  const int T = frames_;
  const size_t N = size_t(num_vertices_);
  const size_t frame_bytes = N * 12;

  // Binary chunk layout (every view on a 4-byte boundary; frame data is a multiple of 4).
  nlohmann::json views = nlohmann::json::array(), accessors = nlohmann::json::array();
  size_t offset = 0;
  auto add_view = [&](size_t length, int target) {
    nlohmann::json v = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}};
    if (target) v["target"] = target;
    views.push_back(v);
    offset = padded4(offset + length);
    return int(views.size()) - 1;
  };
  // Frame 0 positions with bounds.
  float lo[3], hi[3];
  for (int c = 0; c < 3; ++c) lo[c] = std::numeric_limits<float>::infinity(), hi[c] = -lo[c];
  for (size_t i = 0; i < first_.size(); ++i)
    lo[i % 3] = std::min(lo[i % 3], first_[i]), hi[i % 3] = std::max(hi[i % 3], first_[i]);
  accessors.push_back({{"bufferView", add_view(frame_bytes, kArrayBuffer)},
                       {"componentType", kFloat},
                       {"count", N},
                       {"type", "VEC3"},
                       {"min", {lo[0], lo[1], lo[2]}},
                       {"max", {hi[0], hi[1], hi[2]}}});
  accessors.push_back({{"bufferView", add_view(index_bytes_.size(), kElementArrayBuffer)},
                       {"componentType", index_component_},
                       {"count", index_count_},
                       {"type", "SCALAR"}});
  nlohmann::json attributes = {{"POSITION", 0}};
  if (!colors_.empty()) {
    accessors.push_back({{"bufferView", add_view(colors_.size(), kArrayBuffer)},
                         {"componentType", kUnsignedByte},
                         {"normalized", true},
                         {"count", N},
                         {"type", "VEC4"}});
    attributes["COLOR_0"] = int(accessors.size()) - 1;
  }
  nlohmann::json targets = nlohmann::json::array(), names = nlohmann::json::array();
  for (int k = 1; k < T; ++k) {
    const float* b = &bounds_[size_t(k - 1) * 6];
    accessors.push_back({{"bufferView", add_view(frame_bytes, kArrayBuffer)},
                         {"componentType", kFloat},
                         {"count", N},
                         {"type", "VEC3"},
                         {"min", {b[0], b[1], b[2]}},
                         {"max", {b[3], b[4], b[5]}}});
    targets.push_back({{"POSITION", int(accessors.size()) - 1}});
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%04d", k);
    names.push_back(name);
  }
  // Animation tail: sparse weights (index k (T - 1) + k - 1 = 1 at key k), then keyframe times.
  const size_t targets_count = size_t(T - 1);
  std::vector<uint32_t> sparse_indices;
  std::vector<float> ones, times(static_cast<size_t>(T));
  for (size_t k = 1; k < size_t(T); ++k)
    sparse_indices.push_back(uint32_t(k * targets_count + (k - 1))), ones.push_back(1.0f);
  for (int k = 0; k < T; ++k) times[size_t(k)] = float(double(k) / double(fps_));
  nlohmann::json mesh = {{"name", name_}};
  nlohmann::json primitive = {{"attributes", attributes}, {"indices", 1}, {"mode", 4}};
  nlohmann::json animations = nlohmann::json::array();
  if (T > 1) {
    primitive["targets"] = targets;
    mesh["weights"] = std::vector<double>(targets_count, 0.0);
    mesh["extras"] = {{"targetNames", names}};
    const int index_view = add_view(sparse_indices.size() * 4, 0);
    const int value_view = add_view(ones.size() * 4, 0);
    accessors.push_back(
        {{"componentType", kFloat},
         {"count", size_t(T) * targets_count},
         {"type", "SCALAR"},
         {"sparse",
          {{"count", sparse_indices.size()},
           {"indices", {{"bufferView", index_view}, {"byteOffset", 0}, {"componentType", kUnsignedInt}}},
           {"values", {{"bufferView", value_view}, {"byteOffset", 0}}}}}});
    const int output = int(accessors.size()) - 1;
    accessors.push_back({{"bufferView", add_view(times.size() * 4, 0)},
                         {"componentType", kFloat},
                         {"count", T},
                         {"type", "SCALAR"},
                         {"min", {times.front()}},
                         {"max", {times.back()}}});
    const int input = int(accessors.size()) - 1;
    animations.push_back({{"name", clip_},
                          {"samplers", {{{"input", input}, {"output", output}, {"interpolation", "LINEAR"}}}},
                          {"channels", {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}}}}});
  }
  mesh["primitives"] = {primitive};
  const size_t bin_length = offset;
  nlohmann::json extras = {{"amt_format", "mesh-sequence"}, {"amt_format_version", 1}, {"fps", double(fps_)}};
  if (!colors_.empty()) {
    extras["apparel_color"] = {kApparelColor[0], kApparelColor[1], kApparelColor[2]};
    extras["apparel_vertices"] = apparel_vertices_;
  }
  nlohmann::json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", std::string("amt ") + AMT_VERSION}, {"extras", extras}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"name", name_}, {"mesh", 0}}}},
      {"meshes", {mesh}},
      {"accessors", accessors},
      {"bufferViews", views},
      {"buffers", {{{"byteLength", bin_length}}}}};
  if (!animations.empty()) gltf["animations"] = animations;
  const std::string json = gltf.dump();
  const size_t json_chunk = padded4(json.size());
  const size_t total = 12 + 8 + json_chunk + 8 + bin_length;
  AMT_CHECK(total < (size_t(1) << 32), path_, ": buffer: expected less than 4 GiB for a GLB file, found ", total,
            " bytes");

  const std::string tmp = temporary_path(path_);
  register_temporary(tmp);
  std::FILE* out = std::fopen(tmp.c_str(), "wb");
  if (out == nullptr) remove_temporaries();
  AMT_CHECK(out != nullptr, path_, ": output: expected a writable path, found an error creating ", tmp, " (",
            std::strerror(errno), ")");
  try {
    const uint32_t header[3] = {0x46546C67u, 2u, uint32_t(total)};
    write_bytes(out, header, sizeof(header), tmp);
    const uint32_t json_header[2] = {uint32_t(json_chunk), 0x4E4F534Au};
    write_bytes(out, json_header, sizeof(json_header), tmp);
    write_bytes(out, json.data(), json.size(), tmp);
    write_padding(out, json.size(), ' ', tmp);
    const uint32_t bin_header[2] = {uint32_t(bin_length), 0x004E4942u};
    write_bytes(out, bin_header, sizeof(bin_header), tmp);
    write_bytes(out, first_.data(), frame_bytes, tmp);
    write_bytes(out, index_bytes_.data(), index_bytes_.size(), tmp);
    write_padding(out, index_bytes_.size(), '\0', tmp);
    write_bytes(out, colors_.data(), colors_.size(), tmp);  // 4 N bytes: aligned
    std::FILE* data = std::fopen(data_path_.c_str(), "rb");
    AMT_CHECK(data != nullptr, data_path_, ": read: expected the frame data written before, found none");
    std::vector<char> chunk(size_t(1) << 20);
    size_t copied = 0, got = 0;
    while ((got = std::fread(chunk.data(), 1, chunk.size(), data)) > 0)
      write_bytes(out, chunk.data(), got, tmp), copied += got;
    std::fclose(data);
    AMT_CHECK(copied == frame_bytes * targets_count, data_path_, ": read: expected ", frame_bytes * targets_count,
              " bytes of frame data, found ", copied);
    if (T > 1) {
      write_bytes(out, sparse_indices.data(), sparse_indices.size() * 4, tmp);
      write_bytes(out, ones.data(), ones.size() * 4, tmp);
      write_bytes(out, times.data(), times.size() * 4, tmp);
    }
    AMT_CHECK(std::fclose(out) == 0, tmp, ": write: expected to close the file, found an error");
    out = nullptr;
  } catch (...) {
    if (out) std::fclose(out);
    remove_temporaries();
    throw;
  }
  discard_temporary(data_path_);
  replace_with_temporary(tmp, path_);
  finished_ = true;
  first_.clear();
  first_.shrink_to_fit();
  return total;
}

}  // namespace amt
