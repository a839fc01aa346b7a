#include "data_tools/formats/gltf_import.h"

// tinygltf is Debian's libtinygltf (linked by data_tools/formats/CMakeLists.txt), built with its default
// options: no TINYGLTF_* option macros may be defined before including it. Images are not decoded
// (see skip_image) and, for assets parsed from memory, no file is read (see the file callbacks).
#include <tiny_gltf.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <queue>
#include <set>
#include <sstream>
#include <tuple>
#include <unordered_set>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/gltf_buffer.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/geometry/error.h"

namespace amt {

namespace {

// === Limits

constexpr size_t kMaxAccessorValues = size_t(1) << 27;
// Values read from accessors by one import step (loading the animations, gltf_character,
// gltf_vertex_animation): kBaseValueBudget plus kValuesPerBufferByte per byte of the asset's buffers.
// A valid asset reads each stored value a few times at most; this bounds the memory that accessors
// without a buffer view (zeros) or referenced many times could otherwise claim from a small file.
constexpr size_t kBaseValueBudget = size_t(1) << 24;
constexpr size_t kValuesPerBufferByte = 8;
constexpr int kMaxFrames = 1000000;
constexpr size_t kMaxAnimatedVertices = 200000000;  // frames x vertices of a vertex animation
constexpr int kMaxJsonDepth = 256;

using Matrices4d = std::vector<Eigen::Matrix4d, Eigen::aligned_allocator<Eigen::Matrix4d>>;
using RowsX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

std::string hex32(uint32_t v) {
  std::ostringstream out;
  out << "0x" << std::hex << std::uppercase << v;
  return out.str();
}

uint32_t read_le32(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}

// A short, single-line excerpt of a string for error messages.
std::string excerpt(const std::string& s, size_t max_length = 60) {
  std::string out = s.substr(0, max_length);
  for (char& c : out) {
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  }
  if (s.size() > max_length) out += "...";
  return out;
}

// === Container and JSON checks made before tinygltf sees the bytes

// Where the JSON text and the BIN chunk of a GLB lie.
struct GlbLayout {
  size_t json_offset = 0;
  size_t json_size = 0;
  size_t bin_size = 0;  // 0 without a BIN chunk
};

// Checks the GLB header and chunk table (glTF 2.0 section 4.4) against the actual byte count. tinygltf
// checks most of this too, but with messages that name neither the field nor the values, and its BIN
// chunk bound ignores the chunk header (a chunk may end 8 bytes past the data).
GlbLayout check_glb(const uint8_t* data, size_t size, const std::string& src) {
  AMT_CHECK(size >= 12, src, ": GLB header: expected 12 bytes, found ", size, " (truncated file)");
  AMT_CHECK(size <= std::numeric_limits<uint32_t>::max(), src, ": GLB size: expected at most 4 GiB, found ", size,
            " bytes");
  const uint32_t version = read_le32(data + 4);
  AMT_CHECK(version == 2, src, ": GLB header version: expected 2, found ", version);
  const uint32_t length = read_le32(data + 8);
  AMT_CHECK(length == size, src, ": GLB header length: expected the ", length, " bytes it declares, found ", size,
            length > size ? " (truncated file)" : " (trailing bytes)");
  AMT_CHECK(size >= 20, src, ": GLB chunk 0 header: expected 8 bytes at byte 12, found ", size - 12,
            " (truncated file)");
  GlbLayout layout;
  const uint32_t json_length = read_le32(data + 12);
  const uint32_t json_type = read_le32(data + 16);
  AMT_CHECK(json_type == 0x4E4F534Au, src, ": GLB chunk 0 type: expected JSON (0x4E4F534A), found ", hex32(json_type));
  AMT_CHECK(json_length > 0 && json_length <= size - 20, src, ": GLB JSON chunk length: expected 1 to ", size - 20,
            " bytes (the rest of the file), found ", json_length);
  layout.json_offset = 20;
  layout.json_size = json_length;
  const size_t bin_header = 20 + size_t(json_length);
  if (bin_header < size) {
    AMT_CHECK(size - bin_header >= 8, src, ": GLB chunk 1 header: expected 8 bytes at byte ", bin_header, ", found ",
              size - bin_header, " (truncated file)");
    const uint32_t bin_length = read_le32(data + bin_header);
    const uint32_t bin_type = read_le32(data + bin_header + 4);
    AMT_CHECK(bin_type == 0x004E4942u, src, ": GLB chunk 1 type: expected BIN (0x004E4942), found ", hex32(bin_type));
    AMT_CHECK(bin_length <= size - bin_header - 8, src, ": GLB BIN chunk length: expected at most ",
              size - bin_header - 8, " bytes (the rest of the file), found ", bin_length);
    AMT_CHECK(bin_length >= 4 && bin_length % 4 == 0, src,
              ": GLB BIN chunk length: expected a positive multiple of 4, found ", bin_length);
    layout.bin_size = bin_length;
  }
  return layout;
}

// Nesting depth of JSON text (brackets outside strings): tinygltf converts `extras` recursively, so
// deeply nested input would exhaust the stack.
int json_depth(const char* text, size_t size) {
  int depth = 0, max_depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < size; ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '{' || c == '[') {
      max_depth = std::max(max_depth, ++depth);
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return max_depth;
}

// Bytes that tinygltf's base64 decoder produces from the text after a data URI's header.
size_t base64_decoded_size(const std::string& uri, size_t header_size) {
  size_t n = 0;
  for (size_t i = header_size; i < uri.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(uri[i]);
    if (!(std::isalnum(c) || c == '+' || c == '/')) break;
    ++n;
  }
  return n / 4 * 3 + (n % 4 > 1 ? n % 4 - 1 : 0);
}

std::string percent_decode(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && std::isxdigit(static_cast<unsigned char>(s[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(s[i + 2]))) {
      out += static_cast<char>(std::stoi(s.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// True when `file` resolves (links followed) to a path inside the folder `base_dir`: external buffers
// and images of an asset must not leave its folder ("../", an absolute path, a link pointing out).
bool inside_folder(const std::string& base_dir, const std::filesystem::path& file) {
  std::error_code ec;
  const std::filesystem::path base = std::filesystem::weakly_canonical(base_dir, ec);
  if (ec) return false;
  const std::filesystem::path target = std::filesystem::weakly_canonical(file, ec);
  if (ec) return false;
  const auto [b, t] = std::mismatch(base.begin(), base.end(), target.begin(), target.end());
  return b == base.end() && t != target.end();
}

// Checks that the external file of `uri` (field `field`) lies inside the asset's folder.
void check_inside_asset_folder(const std::string& base_dir, const std::string& uri, const std::string& src,
                               const std::string& field) {
  const std::filesystem::path file = std::filesystem::path(base_dir) / percent_decode(uri);
  AMT_CHECK(inside_folder(base_dir, file), src, ": ", field, ".uri: expected a file inside the asset's folder, found '",
            excerpt(uri), "', which resolves to ", file.lexically_normal().string(), " outside it");
}

// Checks the JSON text and its buffers before tinygltf parses it: parse errors with their byte
// position, nesting depth, asset.version, and for every buffer a byteLength that its data can hold
// (data URI, external file or GLB BIN chunk). tinygltf's own messages for these cases are vague or
// quote whole data URIs, and a GLB buffer of byteLength 0 makes it throw std::out_of_range.
void check_json(const char* text, size_t size, bool is_glb, const GlbLayout& glb, const std::string& src,
                const std::string& base_dir) {
  const int depth = json_depth(text, size);
  AMT_CHECK(depth <= kMaxJsonDepth, src, ": JSON: expected nesting at most ", kMaxJsonDepth, " deep, found ", depth);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text, text + size);
  } catch (const nlohmann::json::parse_error& e) {
    fail(src, ": JSON: expected valid JSON, found a syntax error at byte ", e.byte);
  } catch (const nlohmann::json::exception& e) {  // e.g. out_of_range: a number too large for a double
    fail(src, ": JSON: expected valid JSON, found ", excerpt(e.what(), 120));
  }
  AMT_CHECK(doc.is_object(), src, ": JSON: expected an object at the top level, found ", doc.type_name());
  const auto asset = doc.find("asset");
  AMT_CHECK(asset != doc.end() && asset->is_object(), src, ": asset: expected an object, found ",
            asset == doc.end() ? "none" : asset->type_name());
  const auto version = asset->find("version");
  AMT_CHECK(version != asset->end() && version->is_string(), src, ": asset.version: expected a string, found ",
            version == asset->end() ? "none" : version->type_name());
  const std::string version_text = version->get<std::string>();
  AMT_CHECK(version_text.rfind("2.", 0) == 0, src, ": asset.version: expected \"2.0\", found \"", excerpt(version_text),
            "\"");

  // Images are not decoded, but tinygltf reads their files: an external one must be in the folder too.
  const auto images = doc.find("images");
  if (images != doc.end() && images->is_array() && !base_dir.empty()) {
    for (size_t i = 0; i < images->size(); ++i) {
      const nlohmann::json& image = (*images)[i];
      if (!image.is_object()) continue;
      const auto uri = image.find("uri");
      if (uri == image.end() || !uri->is_string()) continue;
      const std::string text = uri->get<std::string>();
      if (text.rfind("data:", 0) != 0)
        check_inside_asset_folder(base_dir, text, src, "images[" + std::to_string(i) + "]");
    }
  }

  const auto buffers = doc.find("buffers");
  if (buffers == doc.end()) return;
  AMT_CHECK(buffers->is_array(), src, ": buffers: expected an array, found ", buffers->type_name());
  for (size_t i = 0; i < buffers->size(); ++i) {
    const nlohmann::json& buffer = (*buffers)[i];
    const std::string field = "buffers[" + std::to_string(i) + "]";
    AMT_CHECK(buffer.is_object(), src, ": ", field, ": expected an object, found ", buffer.type_name());
    const auto length_it = buffer.find("byteLength");
    AMT_CHECK(length_it != buffer.end() && length_it->is_number_unsigned(), src, ": ", field,
              ".byteLength: expected a non-negative integer, found ",
              length_it == buffer.end() ? std::string("none") : excerpt(length_it->dump()));
    const uint64_t byte_length = length_it->get<uint64_t>();
    const auto uri_it = buffer.find("uri");
    if (uri_it == buffer.end()) {
      AMT_CHECK(is_glb, src, ": ", field, ".uri: expected a data URI or a file name, found none (only a GLB's ",
                "buffer may omit it)");
      AMT_CHECK(glb.bin_size > 0, src, ": ", field, ": expected the GLB BIN chunk, found a GLB without one");
      AMT_CHECK(byte_length >= 1 && byte_length <= glb.bin_size, src, ": ", field, ".byteLength: expected 1 to ",
                glb.bin_size, " bytes (the BIN chunk), found ", byte_length);
      continue;
    }
    AMT_CHECK(uri_it->is_string(), src, ": ", field, ".uri: expected a string, found ", uri_it->type_name());
    const std::string uri = uri_it->get<std::string>();
    if (uri.rfind("data:", 0) == 0) {
      static const char* const kHeaders[] = {"data:application/octet-stream;base64,",
                                             "data:application/gltf-buffer;base64,"};
      size_t header_size = 0;
      for (const char* header : kHeaders) {
        if (uri.rfind(header, 0) == 0) header_size = std::strlen(header);
      }
      AMT_CHECK(
          header_size > 0, src, ": ", field,
          ".uri: expected a base64 data URI of type application/octet-stream or application/gltf-buffer, found \"",
          excerpt(uri, 40), "\"");
      const size_t decoded = base64_decoded_size(uri, header_size);
      AMT_CHECK(decoded == byte_length && decoded > 0, src, ": ", field,
                ".uri: expected a data URI holding byteLength = ", byte_length, " bytes, found ", decoded, " bytes");
      continue;
    }
    AMT_CHECK(!uri.empty(), src, ": ", field, ".uri: expected a data URI or a file name, found an empty string");
    AMT_CHECK(!base_dir.empty(), src, ": ", field, ".uri: expected an embedded buffer for an asset parsed from ",
              "memory, found the external file '", excerpt(uri), "'");
    check_inside_asset_folder(base_dir, uri, src, field);
    const std::filesystem::path file = std::filesystem::path(base_dir) / percent_decode(uri);
    std::error_code ec;
    AMT_CHECK(std::filesystem::is_regular_file(file, ec), src, ": ", field, ".uri: expected the external buffer file '",
              excerpt(uri), "' at ", file.string(), ", found no such file");
    const uintmax_t file_size = std::filesystem::file_size(file, ec);
    AMT_CHECK(!ec && file_size == byte_length && byte_length > 0, src, ": ", field, ".uri: expected '", excerpt(uri),
              "' to hold byteLength = ", byte_length, " bytes, found ", ec ? 0 : file_size, " bytes");
  }
}

// === Accessors

int component_size(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;
  }
}

const char* component_type_name(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "FLOAT";
    default:
      return "unknown";
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "unknown";
  }
}

// One component at p, converted as glTF says (section 3.11 for normalized integers).
double load_component(const unsigned char* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    default: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

// The values of an accessor, converted to double: count elements of `components` values each.
struct AccessorData {
  size_t count = 0;
  int components = 0;
  std::vector<double> values;

  double at(size_t element, int component) const { return values[element * components + component]; }
};

// What is left of an import step's value budget (see kBaseValueBudget).
struct ValueBudget {
  size_t left = 0;
};

// Which accessor layouts a reader accepts.
struct AccessorSpec {
  std::vector<int> types;
  std::vector<int> component_types;
};

const AccessorSpec kFloatVec3{{TINYGLTF_TYPE_VEC3}, {TINYGLTF_COMPONENT_TYPE_FLOAT}};
const AccessorSpec kTimes{{TINYGLTF_TYPE_SCALAR}, {TINYGLTF_COMPONENT_TYPE_FLOAT}};
const AccessorSpec kIndices{{TINYGLTF_TYPE_SCALAR},
                            {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                             TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT}};
const AccessorSpec kJoints{{TINYGLTF_TYPE_VEC4},
                           {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}};
const AccessorSpec kWeights{
    {TINYGLTF_TYPE_VEC4},
    {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}};
const AccessorSpec kMatrices{{TINYGLTF_TYPE_MAT4}, {TINYGLTF_COMPONENT_TYPE_FLOAT}};
// Animation outputs: float, or normalized integers (rotations and weights, glTF 2.0 section 3.11).
const AccessorSpec kOutputs{
    {TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4},
    {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
     TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}};

// Checks that [offset, offset + length) lies in a buffer view, and the view in its buffer; returns the
// first byte of the range. `what` names the range in the message.
const unsigned char* view_range(const tinygltf::Model& model, int view_index, uint64_t offset, uint64_t length,
                                const std::string& src, const std::string& what) {
  AMT_CHECK(view_index >= 0 && size_t(view_index) < model.bufferViews.size(), src, ": ", what,
            ".bufferView: expected an index in [0, ", model.bufferViews.size(), "), found ", view_index);
  const tinygltf::BufferView& view = model.bufferViews[size_t(view_index)];
  const std::string view_name = "bufferViews[" + std::to_string(view_index) + "]";
  AMT_CHECK(view.buffer >= 0 && size_t(view.buffer) < model.buffers.size(), src, ": ", view_name,
            ".buffer: expected an index in [0, ", model.buffers.size(), "), found ", view.buffer);
  const size_t buffer_size = model.buffers[size_t(view.buffer)].data.size();
  AMT_CHECK(view.byteOffset <= buffer_size && view.byteLength <= buffer_size - view.byteOffset, src, ": ", view_name,
            ": expected byteOffset + byteLength within buffers[", view.buffer, "] (", buffer_size, " bytes), found ",
            view.byteOffset, " + ", view.byteLength);
  AMT_CHECK(offset <= view.byteLength && length <= view.byteLength - offset, src, ": ", what,
            ": expected its bytes within ", view_name, " (", view.byteLength, " bytes), found bytes ", offset, " to ",
            offset + length);
  return model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + offset;
}

// Reads accessor `index`, checking every byte it touches against its buffer view and buffer before
// reading, applying sparse substitution and normalization, and rejecting NaN or infinite floats.
// `field` names the referring property in messages ("meshes[0].primitives[1].attributes.POSITION").
AccessorData read_accessor(const tinygltf::Model& model, int index, const AccessorSpec& spec, const std::string& src,
                           const std::string& field, ValueBudget& budget) {
  AMT_CHECK(index >= 0 && size_t(index) < model.accessors.size(), src, ": ", field,
            ": expected an accessor index in [0, ", model.accessors.size(), "), found ", index);
  const tinygltf::Accessor& acc = model.accessors[size_t(index)];
  const std::string name = "accessors[" + std::to_string(index) + "] (" + field + ")";

  const bool type_ok = std::find(spec.types.begin(), spec.types.end(), acc.type) != spec.types.end();
  if (!type_ok) {
    std::string expected;
    for (int t : spec.types) expected += std::string(expected.empty() ? "" : " or ") + type_name(t);
    fail(src, ": ", name, ".type: expected ", expected, ", found ", type_name(acc.type));
  }
  const bool component_ok = std::find(spec.component_types.begin(), spec.component_types.end(), acc.componentType) !=
                            spec.component_types.end();
  if (!component_ok) {
    std::string expected;
    for (int c : spec.component_types) expected += std::string(expected.empty() ? "" : " or ") + component_type_name(c);
    fail(src, ": ", name, ".componentType: expected ", expected, ", found ", acc.componentType, " (",
         component_type_name(acc.componentType), ")");
  }
  AMT_CHECK(!acc.normalized || (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT &&
                                acc.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT),
            src, ": ", name, ".normalized: expected false for ", component_type_name(acc.componentType),
            " components, found true");
  const int components = type_components(acc.type);
  const int csize = component_size(acc.componentType);
  AMT_CHECK(acc.count <= kMaxAccessorValues / size_t(components), src, ": ", name, ".count: expected at most ",
            kMaxAccessorValues / size_t(components), " elements, found ", acc.count);
  AMT_CHECK(acc.count * size_t(components) <= budget.left, src, ": ", name, ".count: expected at most ",
            budget.left / size_t(components), " more elements (", kBaseValueBudget, " values + ", kValuesPerBufferByte,
            " per buffer byte for the whole import), found ", acc.count);
  budget.left -= acc.count * size_t(components);

  AccessorData out;
  out.count = acc.count;
  out.components = components;
  out.values.assign(acc.count * size_t(components), 0.0);
  const size_t element_size = size_t(components) * size_t(csize);

  if (acc.bufferView >= 0 && acc.count > 0) {
    AMT_CHECK(size_t(acc.bufferView) < model.bufferViews.size(), src, ": ", name,
              ".bufferView: expected an index in [0, ", model.bufferViews.size(), "), found ", acc.bufferView);
    const tinygltf::BufferView& view = model.bufferViews[size_t(acc.bufferView)];
    const size_t stride = view.byteStride == 0 ? element_size : view.byteStride;
    AMT_CHECK(stride >= element_size && stride <= 252, src, ": bufferViews[", acc.bufferView, "].byteStride: expected ",
              element_size, " to 252 bytes for ", name, ", found ", view.byteStride);
    const uint64_t span = uint64_t(acc.count - 1) * stride + element_size;
    const unsigned char* base = view_range(model, acc.bufferView, acc.byteOffset, span, src, name);
    for (size_t e = 0; e < acc.count; ++e) {
      const unsigned char* p = base + e * stride;
      for (int c = 0; c < components; ++c) {
        out.values[e * components + c] =
            load_component(p + size_t(c) * size_t(csize), acc.componentType, acc.normalized);
      }
    }
  } else if (acc.bufferView < -1) {
    fail(src, ": ", name, ".bufferView: expected an index in [0, ", model.bufferViews.size(), "), found ",
         acc.bufferView);
  }

  if (acc.sparse.isSparse) {
    const auto& sparse = acc.sparse;
    AMT_CHECK(sparse.count >= 1 && size_t(sparse.count) <= acc.count, src, ": ", name, ".sparse.count: expected 1 to ",
              acc.count, ", found ", sparse.count);
    const int isize = component_size(sparse.indices.componentType);
    AMT_CHECK(sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                  sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
                  sparse.indices.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
              src, ": ", name, ".sparse.indices.componentType: expected UNSIGNED_BYTE, UNSIGNED_SHORT or ",
              "UNSIGNED_INT, found ", sparse.indices.componentType);
    AMT_CHECK(sparse.indices.byteOffset >= 0 && sparse.values.byteOffset >= 0, src, ": ", name,
              ".sparse: expected non-negative byte offsets, found ", sparse.indices.byteOffset, " and ",
              sparse.values.byteOffset);
    const unsigned char* indices = view_range(model, sparse.indices.bufferView, uint64_t(sparse.indices.byteOffset),
                                              uint64_t(sparse.count) * uint64_t(isize), src, name + ".sparse.indices");
    const unsigned char* values = view_range(model, sparse.values.bufferView, uint64_t(sparse.values.byteOffset),
                                             uint64_t(sparse.count) * element_size, src, name + ".sparse.values");
    int64_t previous = -1;
    for (int s = 0; s < sparse.count; ++s) {
      const auto target = int64_t(load_component(indices + size_t(s) * isize, sparse.indices.componentType, false));
      AMT_CHECK(target > previous && uint64_t(target) < acc.count, src, ": ", name, ".sparse.indices[", s,
                "]: expected strictly increasing indices below ", acc.count, ", found ", target, " after ", previous);
      previous = target;
      for (int c = 0; c < components; ++c) {
        out.values[size_t(target) * components + c] =
            load_component(values + size_t(s) * element_size + size_t(c) * csize, acc.componentType, acc.normalized);
      }
    }
  }

  if (acc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
    for (size_t i = 0; i < out.values.size(); ++i) {
      AMT_CHECK(std::isfinite(out.values[i]), src, ": ", name, ": expected finite values, found ", out.values[i],
                " at element ", i / components);
    }
  }
  return out;
}

// === Node transforms

// A node's rest transform: TRS, or a matrix (column-major, as stored).
struct NodeRest {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  bool has_matrix = false;
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
};

Eigen::Matrix4d trs_matrix(const Eigen::Vector3d& t, const Eigen::Quaterniond& r, const Eigen::Vector3d& s) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = r.toRotationMatrix() * s.asDiagonal();
  m.topRightCorner<3, 1>() = t;
  return m;
}

// The rotation closest to A (polar decomposition through the SVD).
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& A) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  if ((U * svd.matrixV().transpose()).determinant() < 0) U.col(2) *= -1.0;
  return U * svd.matrixV().transpose();
}

// === Animation channels

enum class ChannelPath { kTranslation, kRotation, kScale, kWeights };
enum class Interpolation { kStep, kLinear, kCubicSpline };

// One channel with its keys read: `width` values per key (3, 4, or the morph target count), and for
// CUBICSPLINE three groups per key (in-tangent, value, out-tangent).
struct Channel {
  int node = -1;
  ChannelPath path = ChannelPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  int width = 0;
  std::vector<double> times;
  std::vector<double> values;
};

struct Clip {
  std::string name;
  double start = 0.0;
  double end = 0.0;
  std::vector<Channel> channels;
};

// Value of a channel at time t, into out (width values).
void sample_channel(const Channel& ch, double t, double* out) {
  const int w = ch.width;
  const size_t keys = ch.times.size();
  const bool cubic = ch.interpolation == Interpolation::kCubicSpline;
  // The value of key k (the middle group of a cubic spline key).
  auto value = [&](size_t k) { return ch.values.data() + (cubic ? (3 * k + 1) * w : k * w); };
  auto copy_key = [&](size_t k) { std::copy(value(k), value(k) + w, out); };
  if (t <= ch.times.front() || keys == 1) return copy_key(0);
  if (t >= ch.times.back()) return copy_key(keys - 1);
  const size_t k = size_t(std::upper_bound(ch.times.begin(), ch.times.end(), t) - ch.times.begin()) - 1;
  const double dt = ch.times[k + 1] - ch.times[k];
  const double s = (t - ch.times[k]) / dt;
  switch (ch.interpolation) {
    case Interpolation::kStep:
      return copy_key(k);
    case Interpolation::kLinear:
      if (ch.path == ChannelPath::kRotation) {
        const double* a = value(k);
        const double* b = value(k + 1);
        const Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
        const Eigen::Quaterniond q = qa.normalized().slerp(s, qb.normalized());
        out[0] = q.x(), out[1] = q.y(), out[2] = q.z(), out[3] = q.w();
      } else {
        const double* a = value(k);
        const double* b = value(k + 1);
        for (int i = 0; i < w; ++i) out[i] = a[i] + s * (b[i] - a[i]);
      }
      return;
    case Interpolation::kCubicSpline: {
      // glTF 2.0 Appendix C: p(s) = (2s^3 - 3s^2 + 1) v_k + dt (s^3 - 2s^2 + s) b_k
      //                            + (-2s^3 + 3s^2) v_k+1 + dt (s^3 - s^2) a_k+1
      const double s2 = s * s, s3 = s2 * s;
      const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
      const double* v0 = value(k);
      const double* b0 = v0 + w;  // out-tangent of key k
      const double* v1 = value(k + 1);
      const double* a1 = v1 - w;  // in-tangent of key k + 1
      for (int i = 0; i < w; ++i) out[i] = h00 * v0[i] + h10 * dt * b0[i] + h01 * v1[i] + h11 * dt * a1[i];
      if (ch.path == ChannelPath::kRotation) {
        const double n = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
        if (n > 0) {
          for (int i = 0; i < 4; ++i) out[i] /= n;
        }
      }
      return;
    }
  }
}

}  // namespace

// === The asset

struct GltfAsset::Impl {
  std::string source;
  tinygltf::Model model;
  std::vector<GltfAnimationInfo> animations;
  std::vector<Clip> clips;         // per animation, keys read and checked
  std::vector<int> parent;         // per node, -1 for roots
  std::vector<int> node_order;     // every node, parents before children
  std::vector<int> scene_nodes;    // nodes of the default scene, depth-first preorder
  std::vector<NodeRest> rest;      // per node
  Matrices4d rest_world;           // per node, global rest transform
  std::vector<int> morph_targets;  // per mesh, number of morph targets
  size_t value_budget = 0;         // values one import step may read (see kBaseValueBudget)
};

GltfAsset::GltfAsset(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

const std::string& GltfAsset::source() const {
  return impl_->source;
}

const std::vector<GltfAnimationInfo>& GltfAsset::animations() const {
  return impl_->animations;
}

namespace {

using Impl = GltfAsset::Impl;

// tinygltf's image callback: images are not needed, so they are accepted without decoding.
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

// tinygltf's file callbacks: files are visible only under the asset's folder (tinygltf also searches
// the working directory), and none at all for an asset parsed from memory without a folder.
struct FileAccess {
  std::string base_dir;
};

bool file_exists(const std::string& path, void* user) {
  const auto* access = static_cast<const FileAccess*>(user);
  if (access->base_dir.empty() || !inside_folder(access->base_dir, path)) return false;
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec) && std::filesystem::file_size(path, ec) <= max_input_bytes();
}

std::string expand_path(const std::string& path, void*) {
  return path;
}

bool read_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  if (!file_exists(path, user)) {  // checked before opening: a FIFO would block
    if (err) *err += "cannot read " + path + " (outside the asset's folder, not a regular file or too large)";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in.good()) {
    if (err) *err += "cannot read " + path;
    return false;
  }
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return !in.bad();
}

bool write_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing is not allowed while importing";
  return false;
}

void check_finite(const std::vector<double>& values, const std::string& src, const std::string& field) {
  for (double v : values) {
    AMT_CHECK(std::isfinite(v), src, ": ", field, ": expected finite values, found ", v);
  }
}

// Rest transforms, hierarchy and scene of the model; throws on any bad index.
void check_nodes(Impl& a) {
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;
  const size_t N = m.nodes.size();
  a.parent.assign(N, -1);
  a.rest.resize(N);
  for (size_t n = 0; n < N; ++n) {
    const tinygltf::Node& node = m.nodes[n];
    const std::string field = "nodes[" + std::to_string(n) + "]";
    for (int c : node.children) {
      AMT_CHECK(c >= 0 && size_t(c) < N && size_t(c) != n, src, ": ", field, ".children: expected node indices in [0, ",
                N, ") other than ", n, ", found ", c);
      AMT_CHECK(a.parent[size_t(c)] == -1, src, ": ", field, ".children: expected each node to have one parent, ",
                "found node ", c, " also a child of node ", a.parent[size_t(c)]);
      a.parent[size_t(c)] = int(n);
    }
    AMT_CHECK(node.mesh >= -1 && node.mesh < int(m.meshes.size()), src, ": ", field, ".mesh: expected an index in [0, ",
              m.meshes.size(), "), found ", node.mesh);
    AMT_CHECK(node.skin >= -1 && node.skin < int(m.skins.size()), src, ": ", field, ".skin: expected an index in [0, ",
              m.skins.size(), "), found ", node.skin);
    NodeRest& r = a.rest[n];
    AMT_CHECK(node.translation.empty() || node.translation.size() == 3, src, ": ", field,
              ".translation: expected 3 values, found ", node.translation.size());
    AMT_CHECK(node.rotation.empty() || node.rotation.size() == 4, src, ": ", field,
              ".rotation: expected 4 values, found ", node.rotation.size());
    AMT_CHECK(node.scale.empty() || node.scale.size() == 3, src, ": ", field, ".scale: expected 3 values, found ",
              node.scale.size());
    AMT_CHECK(node.matrix.empty() || node.matrix.size() == 16, src, ": ", field, ".matrix: expected 16 values, found ",
              node.matrix.size());
    check_finite(node.translation, src, field + ".translation");
    check_finite(node.rotation, src, field + ".rotation");
    check_finite(node.scale, src, field + ".scale");
    check_finite(node.matrix, src, field + ".matrix");
    check_finite(node.weights, src, field + ".weights");
    if (!node.translation.empty()) r.translation = Eigen::Vector3d(node.translation.data());
    if (!node.scale.empty()) r.scale = Eigen::Vector3d(node.scale.data());
    if (!node.rotation.empty()) {
      r.rotation = Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
      const double norm = r.rotation.norm();
      AMT_CHECK(norm > 1e-6, src, ": ", field, ".rotation: expected a unit quaternion, found norm ", norm);
      r.rotation.normalize();
    }
    if (!node.matrix.empty()) {
      r.has_matrix = true;
      r.matrix = Eigen::Map<const Eigen::Matrix4d>(node.matrix.data());  // column-major, as glTF stores it
      AMT_CHECK(r.matrix.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-6), src, ": ", field,
                ".matrix: expected an affine transform (last row 0 0 0 1), found ", r.matrix(3, 0), " ", r.matrix(3, 1),
                " ", r.matrix(3, 2), " ", r.matrix(3, 3));
      r.matrix.row(3) << 0, 0, 0, 1;
    }
  }
  // Parents before children; nodes never reached from a root lie on a cycle.
  a.node_order.clear();
  for (size_t n = 0; n < N; ++n) {
    if (a.parent[n] == -1) a.node_order.push_back(int(n));
  }
  for (size_t i = 0; i < a.node_order.size(); ++i) {
    for (int c : m.nodes[size_t(a.node_order[i])].children) a.node_order.push_back(c);
  }
  if (a.node_order.size() != N) {
    std::vector<bool> reached(N, false);
    for (int n : a.node_order) reached[size_t(n)] = true;
    const size_t on_cycle = size_t(std::find(reached.begin(), reached.end(), false) - reached.begin());
    fail(src, ": nodes: expected a hierarchy without cycles, found a cycle through node ", on_cycle);
  }
  a.rest_world.assign(N, Eigen::Matrix4d::Identity());
  for (int n : a.node_order) {
    const NodeRest& r = a.rest[size_t(n)];
    const Eigen::Matrix4d local = r.has_matrix ? r.matrix : trs_matrix(r.translation, r.rotation, r.scale);
    const int p = a.parent[size_t(n)];
    a.rest_world[size_t(n)] = p < 0 ? local : Eigen::Matrix4d(a.rest_world[size_t(p)] * local);
  }

  // The default scene: `scene`, else the first scene, else every root node.
  AMT_CHECK(m.defaultScene >= -1 && m.defaultScene < int(m.scenes.size()), src, ": scene: expected an index in [0, ",
            m.scenes.size(), "), found ", m.defaultScene);
  std::vector<int> roots;
  if (!m.scenes.empty()) {
    const size_t s = m.defaultScene >= 0 ? size_t(m.defaultScene) : 0;
    for (int n : m.scenes[s].nodes) {
      AMT_CHECK(n >= 0 && size_t(n) < N, src, ": scenes[", s, "].nodes: expected node indices in [0, ", N, "), found ",
                n);
      roots.push_back(n);
    }
  } else {
    for (size_t n = 0; n < N; ++n) {
      if (a.parent[n] == -1) roots.push_back(int(n));
    }
  }
  std::vector<bool> listed(N, false);
  std::vector<int> stack(roots.rbegin(), roots.rend());
  while (!stack.empty()) {
    const int n = stack.back();
    stack.pop_back();
    if (listed[size_t(n)]) continue;
    listed[size_t(n)] = true;
    a.scene_nodes.push_back(n);
    const auto& children = m.nodes[size_t(n)].children;
    stack.insert(stack.end(), children.rbegin(), children.rend());
  }
}

void check_meshes_and_skins(Impl& a) {
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;
  a.morph_targets.assign(m.meshes.size(), 0);
  for (size_t i = 0; i < m.meshes.size(); ++i) {
    const tinygltf::Mesh& mesh = m.meshes[i];
    const std::string field = "meshes[" + std::to_string(i) + "]";
    const size_t targets = mesh.primitives.empty() ? 0 : mesh.primitives[0].targets.size();
    for (size_t p = 0; p < mesh.primitives.size(); ++p) {
      AMT_CHECK(mesh.primitives[p].targets.size() == targets, src, ": ", field, ".primitives[", p,
                "].targets: expected ", targets, " morph targets like primitive 0, found ",
                mesh.primitives[p].targets.size());
    }
    AMT_CHECK(mesh.weights.empty() || mesh.weights.size() == targets, src, ": ", field, ".weights: expected ", targets,
              " values (one per morph target), found ", mesh.weights.size());
    check_finite(mesh.weights, src, field + ".weights");
    a.morph_targets[i] = int(targets);
  }
  for (size_t n = 0; n < m.nodes.size(); ++n) {
    const tinygltf::Node& node = m.nodes[n];
    if (node.mesh >= 0) {
      AMT_CHECK(node.weights.empty() || node.weights.size() == size_t(a.morph_targets[size_t(node.mesh)]), src,
                ": nodes[", n, "].weights: expected ", a.morph_targets[size_t(node.mesh)],
                " values (one per morph target of its mesh), found ", node.weights.size());
    }
  }
  for (size_t s = 0; s < m.skins.size(); ++s) {
    const tinygltf::Skin& skin = m.skins[s];
    std::unordered_set<int> seen;
    AMT_CHECK(!skin.joints.empty(), src, ": skins[", s, "].joints: expected at least 1 joint, found none");
    for (int j : skin.joints) {
      AMT_CHECK(j >= 0 && size_t(j) < m.nodes.size(), src, ": skins[", s, "].joints: expected node indices in [0, ",
                m.nodes.size(), "), found ", j);
      AMT_CHECK(seen.insert(j).second, src, ": skins[", s, "].joints: expected each node once, found node ", j,
                " twice");
    }
  }
}

// Reads and checks every animation: channel targets, samplers, keyframe times and values.
void read_animations(Impl& a) {
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;
  ValueBudget budget{a.value_budget};
  for (size_t i = 0; i < m.animations.size(); ++i) {
    const tinygltf::Animation& anim = m.animations[i];
    const std::string field = "animations[" + std::to_string(i) + "]";
    Clip clip;
    clip.name = anim.name.empty() ? "animation_" + std::to_string(i) : anim.name;
    clip.start = std::numeric_limits<double>::infinity();
    clip.end = -std::numeric_limits<double>::infinity();
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& channel = anim.channels[c];
      const std::string cfield = field + ".channels[" + std::to_string(c) + "]";
      AMT_CHECK(channel.sampler >= 0 && size_t(channel.sampler) < anim.samplers.size(), src, ": ", cfield,
                ".sampler: expected an index in [0, ", anim.samplers.size(), "), found ", channel.sampler);
      if (channel.target_node < 0) continue;  // targets defined by extensions only
      AMT_CHECK(size_t(channel.target_node) < m.nodes.size(), src, ": ", cfield,
                ".target.node: expected an index in [0, ", m.nodes.size(), "), found ", channel.target_node);
      Channel ch;
      ch.node = channel.target_node;
      const std::string& path = channel.target_path;
      if (path == "translation") {
        ch.path = ChannelPath::kTranslation, ch.width = 3;
      } else if (path == "rotation") {
        ch.path = ChannelPath::kRotation, ch.width = 4;
      } else if (path == "scale") {
        ch.path = ChannelPath::kScale, ch.width = 3;
      } else if (path == "weights") {
        ch.path = ChannelPath::kWeights;
        const int mesh = m.nodes[size_t(ch.node)].mesh;
        ch.width = mesh >= 0 ? a.morph_targets[size_t(mesh)] : 0;
        AMT_CHECK(ch.width > 0, src, ": ", cfield, ".target: expected a node whose mesh has morph targets for path ",
                  "\"weights\", found node ", ch.node);
      } else {
        continue;  // paths of extensions (KHR_animation_pointer): not amt's concern
      }
      AMT_CHECK(ch.path == ChannelPath::kWeights || !a.rest[size_t(ch.node)].has_matrix, src, ": ", cfield,
                ".target.node: expected an animated node to have TRS properties, found node ", ch.node,
                " with a matrix");
      const tinygltf::AnimationSampler& sampler = anim.samplers[size_t(channel.sampler)];
      const std::string sfield = field + ".samplers[" + std::to_string(channel.sampler) + "]";
      if (sampler.interpolation == "LINEAR" || sampler.interpolation.empty()) {
        ch.interpolation = Interpolation::kLinear;
      } else if (sampler.interpolation == "STEP") {
        ch.interpolation = Interpolation::kStep;
      } else if (sampler.interpolation == "CUBICSPLINE") {
        ch.interpolation = Interpolation::kCubicSpline;
      } else {
        fail(src, ": ", sfield, ".interpolation: expected LINEAR, STEP or CUBICSPLINE, found \"",
             excerpt(sampler.interpolation), "\"");
      }
      const AccessorData input = read_accessor(m, sampler.input, kTimes, src, sfield + ".input", budget);
      AMT_CHECK(input.count >= 1, src, ": ", sfield, ".input: expected at least 1 keyframe time, found none");
      ch.times = input.values;
      for (size_t k = 1; k < ch.times.size(); ++k) {
        AMT_CHECK(ch.times[k] >= ch.times[k - 1], src, ": ", sfield, ".input: expected increasing keyframe times, ",
                  "found ", ch.times[k], " after ", ch.times[k - 1], " at key ", k);
      }
      const AccessorData output = read_accessor(m, sampler.output, kOutputs, src, sfield + ".output", budget);
      const size_t per_key = size_t(ch.width) * (ch.interpolation == Interpolation::kCubicSpline ? 3 : 1);
      AMT_CHECK(output.values.size() == input.count * per_key, src, ": ", sfield, ".output: expected ",
                input.count * per_key, " values (", input.count, " keys x ", per_key, ") for path \"", path,
                "\", found ", output.values.size());
      const int expected_components = ch.path == ChannelPath::kWeights ? 1 : ch.width;
      AMT_CHECK(output.components == expected_components, src, ": ", sfield, ".output: expected ", expected_components,
                " components per element for path \"", path, "\", found ", output.components);
      ch.values = output.values;
      if (ch.path == ChannelPath::kRotation) {
        for (size_t k = 0; k * 4 < ch.values.size(); ++k) {
          const double* q = &ch.values[4 * k];
          const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
          // Tangents of a cubic spline may be zero; values may not.
          const bool is_tangent = ch.interpolation == Interpolation::kCubicSpline && k % 3 != 1;
          AMT_CHECK(is_tangent || norm > 1e-6, src, ": ", sfield, ".output: expected unit quaternions, found norm ",
                    norm, " at element ", k);
        }
      }
      clip.start = std::min(clip.start, ch.times.front());
      clip.end = std::max(clip.end, ch.times.back());
      clip.channels.push_back(std::move(ch));
    }
    if (clip.channels.empty()) clip.start = clip.end = 0.0;
    GltfAnimationInfo info;
    info.name = clip.name;
    info.start = float(clip.start);
    info.end = float(clip.end);
    info.num_channels = int(anim.channels.size());
    a.animations.push_back(info);
    a.clips.push_back(std::move(clip));
  }
}

// === Evaluation of the node graph

// Global transforms of the nodes at one time.
struct Pose {
  Matrices4d world;  // per node
};

// Morph target weights of a node with a mesh at time t of clip (nullptr: the rest pose): a "weights"
// channel on the node, else the node's default weights, else its mesh's, else zeros.
std::vector<double> node_weights(const Impl& a, const Clip* clip, double t, int node) {
  const tinygltf::Node& n = a.model.nodes[size_t(node)];
  if (n.mesh < 0) return {};
  std::vector<double> weights(size_t(a.morph_targets[size_t(n.mesh)]), 0.0);
  if (!n.weights.empty()) {
    weights = n.weights;
  } else if (!a.model.meshes[size_t(n.mesh)].weights.empty()) {
    weights = a.model.meshes[size_t(n.mesh)].weights;
  }
  if (clip) {
    for (const Channel& ch : clip->channels) {
      if (ch.node == node && ch.path == ChannelPath::kWeights) sample_channel(ch, t, weights.data());
    }
  }
  return weights;
}

// The node transforms at time t of clip (nullptr: the rest pose).
void evaluate_pose(const Impl& a, const Clip* clip, double t, Pose& pose) {
  const size_t N = a.model.nodes.size();
  std::vector<NodeRest> local = a.rest;
  if (clip) {
    double v[4];
    for (const Channel& ch : clip->channels) {
      NodeRest& r = local[size_t(ch.node)];
      switch (ch.path) {
        case ChannelPath::kTranslation:
          sample_channel(ch, t, v);
          r.translation = Eigen::Vector3d(v[0], v[1], v[2]);
          break;
        case ChannelPath::kRotation: {
          sample_channel(ch, t, v);
          const Eigen::Quaterniond q(v[3], v[0], v[1], v[2]);
          if (q.norm() > 1e-12) r.rotation = q.normalized();
          break;
        }
        case ChannelPath::kScale:
          sample_channel(ch, t, v);
          r.scale = Eigen::Vector3d(v[0], v[1], v[2]);
          break;
        case ChannelPath::kWeights:
          break;  // see node_weights
      }
    }
  }
  pose.world.resize(N);
  for (int n : a.node_order) {
    const NodeRest& r = local[size_t(n)];
    const Eigen::Matrix4d l = r.has_matrix ? r.matrix : trs_matrix(r.translation, r.rotation, r.scale);
    const int p = a.parent[size_t(n)];
    pose.world[size_t(n)] = p < 0 ? l : Eigen::Matrix4d(pose.world[size_t(p)] * l);
  }
}

// The clip called `name` ("" = the first; nullptr when the asset has none and no name was asked).
const Clip* find_clip(const Impl& a, const std::string& name) {
  if (name.empty()) return a.clips.empty() ? nullptr : &a.clips[0];
  for (const Clip& c : a.clips) {
    if (c.name == name) return &c;
  }
  std::string names;
  for (const Clip& c : a.clips) names += (names.empty() ? "" : ", ") + c.name;
  fail(a.source, ": animations: expected a clip called \"", name, "\", found ",
       names.empty() ? std::string("no clips") : "only " + names);
}

// Frame count of a clip of `duration` seconds at `fps`.
int frame_count(const Impl& a, const Clip* clip, float fps) {
  AMT_CHECK(std::isfinite(fps) && fps > 0.0f && fps <= 1000.0f, a.source,
            ": fps: expected a frame rate in (0, 1000], found ", fps);
  if (!clip) return 1;
  const double frames = std::floor((clip->end - clip->start) * fps + 1e-4) + 1.0;
  AMT_CHECK(frames <= kMaxFrames, a.source, ": animation \"", clip->name, "\": expected at most ", kMaxFrames,
            " frames at ", fps, " fps, found ", frames, " (", clip->end - clip->start, " s)");
  return int(frames);
}

// === Meshes

// One mesh's primitives merged: positions, triangles, morph target deltas and skin influences.
struct MeshGeometry {
  RowsX3d V;
  std::vector<int32_t> faces;    // 3 per triangle, indices into V
  std::vector<RowsX3d> targets;  // per morph target, #V by 3 position deltas
  int slots = 0;                 // influences per vertex (4 per JOINTS_n / WEIGHTS_n set)
  std::vector<int> joints;       // #V * slots skin joint indices
  std::vector<double> weights;   // #V * slots weights, normalised per vertex
};

const char* mode_name(int mode) {
  switch (mode) {
    case TINYGLTF_MODE_POINTS:
      return "POINTS";
    case TINYGLTF_MODE_LINE:
      return "LINES";
    case TINYGLTF_MODE_LINE_LOOP:
      return "LINE_LOOP";
    case TINYGLTF_MODE_LINE_STRIP:
      return "LINE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_STRIP:
      return "TRIANGLE_STRIP";
    case TINYGLTF_MODE_TRIANGLE_FAN:
      return "TRIANGLE_FAN";
    default:
      return "unknown";
  }
}

// Reads mesh `mesh_index`. With skin_joints > 0 every primitive needs JOINTS_0 / WEIGHTS_0 with indices
// below skin_joints; a vertex whose weights are all 0 binds to skin joint `fallback_joint`.
MeshGeometry read_mesh(const Impl& a, int mesh_index, int skin_joints, int fallback_joint, ValueBudget& budget) {
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;
  const tinygltf::Mesh& mesh = m.meshes[size_t(mesh_index)];
  const int num_targets = a.morph_targets[size_t(mesh_index)];
  const std::string mesh_field = "meshes[" + std::to_string(mesh_index) + "]";
  const std::string mesh_label = mesh_field + (mesh.name.empty() ? "" : " '" + excerpt(mesh.name) + "'");

  // Read every primitive first, then merge.
  struct Part {
    AccessorData positions;
    std::vector<int32_t> faces;
    std::vector<AccessorData> targets;  // count 0 where the target has no POSITION
    std::vector<AccessorData> joints, weights;
  };
  std::vector<Part> parts(mesh.primitives.size());
  size_t total_vertices = 0;
  int max_sets = 0;
  for (size_t p = 0; p < mesh.primitives.size(); ++p) {
    const tinygltf::Primitive& prim = mesh.primitives[p];
    const std::string field = mesh_field + ".primitives[" + std::to_string(p) + "]";
    AMT_CHECK(prim.mode == TINYGLTF_MODE_TRIANGLES || prim.mode == -1, src, ": ", mesh_label, ".primitives[", p,
              "].mode: expected 4 (TRIANGLES), found ", prim.mode, " (", mode_name(prim.mode), ")");
    Part& part = parts[p];
    const auto pos = prim.attributes.find("POSITION");
    AMT_CHECK(pos != prim.attributes.end(), src, ": ", field, ".attributes.POSITION: expected an accessor, found none");
    part.positions = read_accessor(m, pos->second, kFloatVec3, src, field + ".attributes.POSITION", budget);
    const size_t n = part.positions.count;
    AMT_CHECK(n <= size_t(std::numeric_limits<int32_t>::max()) - total_vertices, src, ": ", field,
              ".attributes.POSITION: expected fewer than 2^31 vertices in all, found more");
    if (prim.indices >= 0) {
      const AccessorData indices = read_accessor(m, prim.indices, kIndices, src, field + ".indices", budget);
      AMT_CHECK(indices.count % 3 == 0, src, ": ", field, ".indices: expected a multiple of 3 indices (TRIANGLES), ",
                "found ", indices.count);
      part.faces.resize(indices.count);
      for (size_t i = 0; i < indices.count; ++i) {
        const double v = indices.values[i];
        AMT_CHECK(v < double(n), src, ": ", field, ".indices: expected vertex indices below the vertex count ", n,
                  ", found ", uint64_t(v), " at index ", i);
        part.faces[i] = int32_t(v);
      }
    } else {
      AMT_CHECK(n % 3 == 0, src, ": ", field, ".attributes.POSITION: expected a multiple of 3 vertices for ",
                "TRIANGLES without indices, found ", n);
      part.faces.resize(n);
      for (size_t i = 0; i < n; ++i) part.faces[i] = int32_t(i);
    }
    part.targets.resize(size_t(num_targets));
    for (int t = 0; t < num_targets; ++t) {
      const auto& target = prim.targets[size_t(t)];
      const auto tp = target.find("POSITION");
      if (tp == target.end()) continue;
      const std::string tfield = field + ".targets[" + std::to_string(t) + "].POSITION";
      part.targets[size_t(t)] = read_accessor(m, tp->second, kFloatVec3, src, tfield, budget);
      AMT_CHECK(part.targets[size_t(t)].count == n, src, ": ", tfield, ": expected ", n,
                " elements (the POSITION count), found ", part.targets[size_t(t)].count);
    }
    if (skin_joints > 0) {
      for (int set = 0;; ++set) {
        const auto j = prim.attributes.find("JOINTS_" + std::to_string(set));
        const auto w = prim.attributes.find("WEIGHTS_" + std::to_string(set));
        if (j == prim.attributes.end() && w == prim.attributes.end()) break;
        const std::string jname = field + ".attributes.JOINTS_" + std::to_string(set);
        const std::string wname = field + ".attributes.WEIGHTS_" + std::to_string(set);
        AMT_CHECK(j != prim.attributes.end() && w != prim.attributes.end(), src, ": ",
                  j == prim.attributes.end() ? jname : wname, ": expected an accessor paired with ",
                  j == prim.attributes.end() ? wname : jname, ", found none");
        part.joints.push_back(read_accessor(m, j->second, kJoints, src, jname, budget));
        part.weights.push_back(read_accessor(m, w->second, kWeights, src, wname, budget));
        AMT_CHECK(part.joints.back().count == n && part.weights.back().count == n, src, ": ", jname, ": expected ", n,
                  " elements (the POSITION count) in JOINTS and WEIGHTS, found ", part.joints.back().count, " and ",
                  part.weights.back().count);
      }
      AMT_CHECK(!part.joints.empty(), src, ": ", field, ".attributes.JOINTS_0: expected JOINTS_0 and WEIGHTS_0 on ",
                "every primitive of a skinned mesh, found none");
      max_sets = std::max(max_sets, int(part.joints.size()));
    }
    total_vertices += n;
  }

  // Targets without POSITION still take #V x 3 values each: they count against the budget too.
  AMT_CHECK(size_t(num_targets) * total_vertices * 3 <= budget.left, src, ": ", mesh_field, ".primitives: expected ",
            "at most ", budget.left, " more morph target values for the whole import, found ", num_targets,
            " targets x ", total_vertices, " vertices x 3");
  budget.left -= size_t(num_targets) * total_vertices * 3;
  MeshGeometry g;
  g.V.resize(Eigen::Index(total_vertices), 3);
  g.targets.assign(size_t(num_targets), RowsX3d::Zero(Eigen::Index(total_vertices), 3));
  g.slots = 4 * max_sets;
  g.joints.assign(total_vertices * size_t(g.slots), 0);
  g.weights.assign(total_vertices * size_t(g.slots), 0.0);
  size_t offset = 0;
  for (size_t p = 0; p < parts.size(); ++p) {
    const Part& part = parts[p];
    const size_t n = part.positions.count;
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) g.V(Eigen::Index(offset + i), c) = part.positions.at(i, c);
    }
    for (int32_t f : part.faces) g.faces.push_back(int32_t(offset) + f);
    for (int t = 0; t < num_targets; ++t) {
      const AccessorData& target = part.targets[size_t(t)];
      for (size_t i = 0; i < target.count; ++i) {
        for (int c = 0; c < 3; ++c) g.targets[size_t(t)](Eigen::Index(offset + i), c) = target.at(i, c);
      }
    }
    const std::string field = mesh_field + ".primitives[" + std::to_string(p) + "]";
    for (size_t i = 0; i < n && skin_joints > 0; ++i) {
      int* joints = &g.joints[(offset + i) * size_t(g.slots)];
      double* weights = &g.weights[(offset + i) * size_t(g.slots)];
      double sum = 0.0;
      for (size_t set = 0; set < part.joints.size(); ++set) {
        for (int c = 0; c < 4; ++c) {
          const double w = part.weights[set].at(i, c);
          const double j = part.joints[set].at(i, c);
          AMT_CHECK(w >= 0.0, src, ": ", field, ".attributes.WEIGHTS_", set, ": expected non-negative weights, found ",
                    w, " at vertex ", i);
          if (w == 0.0) continue;  // the joint index of a zero weight is not used
          AMT_CHECK(j < skin_joints, src, ": ", field, ".attributes.JOINTS_", set, ": expected joint indices below ",
                    "the skin's ", skin_joints, " joints, found ", j, " at vertex ", i);
          joints[set * 4 + size_t(c)] = int(j);
          weights[set * 4 + size_t(c)] = w;
          sum += w;
        }
      }
      if (sum > 0.0) {
        for (int s = 0; s < g.slots; ++s) weights[s] /= sum;
      } else {
        joints[0] = fallback_joint;
        weights[0] = 1.0;
      }
    }
    offset += n;
  }
  return g;
}

// Positions of a mesh with morph weights applied: V + sum_t w_t D_t.
RowsX3d morphed(const MeshGeometry& g, const std::vector<double>& weights) {
  RowsX3d P = g.V;
  for (size_t t = 0; t < g.targets.size() && t < weights.size(); ++t) {
    if (weights[t] != 0.0) P += weights[t] * g.targets[t];
  }
  return P;
}

// The inverse bind matrices of a skin (identity when the skin has none).
Matrices4d inverse_bind_matrices(const Impl& a, int skin_index, ValueBudget& budget) {
  const tinygltf::Skin& skin = a.model.skins[size_t(skin_index)];
  Matrices4d ibm(skin.joints.size(), Eigen::Matrix4d::Identity());
  if (skin.inverseBindMatrices < 0) return ibm;
  const std::string field = "skins[" + std::to_string(skin_index) + "].inverseBindMatrices";
  const AccessorData data = read_accessor(a.model, skin.inverseBindMatrices, kMatrices, a.source, field, budget);
  AMT_CHECK(data.count >= skin.joints.size(), a.source, ": ", field, ": expected ", skin.joints.size(),
            " matrices (one per joint), found ", data.count);
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    ibm[j] = Eigen::Map<const Eigen::Matrix4d>(&data.values[16 * j]);  // column-major
  }
  return ibm;
}

// The skin joint that is a hierarchy root among the skin's joints (the first in the skin's list).
int first_root_joint(const Impl& a, int skin_index) {
  const tinygltf::Skin& skin = a.model.skins[size_t(skin_index)];
  const std::unordered_set<int> joints(skin.joints.begin(), skin.joints.end());
  for (size_t k = 0; k < skin.joints.size(); ++k) {
    int p = a.parent[size_t(skin.joints[k])];
    while (p >= 0 && !joints.count(p)) p = a.parent[size_t(p)];
    if (p < 0) return int(k);
  }
  return 0;
}

// Skins positions P (#V by 3) with skin joint matrices M (per skin joint, world from mesh space).
RowsX3d skin_positions(const MeshGeometry& g, const RowsX3d& P, const Matrices4d& M) {
  RowsX3d out(P.rows(), 3);
  for (Eigen::Index i = 0; i < P.rows(); ++i) {
    Eigen::Matrix4d B = Eigen::Matrix4d::Zero();
    for (int s = 0; s < g.slots; ++s) {
      const double w = g.weights[size_t(i) * size_t(g.slots) + size_t(s)];
      if (w != 0.0) B += w * M[size_t(g.joints[size_t(i) * size_t(g.slots) + size_t(s)])];
    }
    out.row(i) = (B.topLeftCorner<3, 3>() * P.row(i).transpose() + B.topRightCorner<3, 1>()).transpose();
  }
  return out;
}

// Mesh nodes of the default scene, in scene order.
std::vector<int> scene_mesh_nodes(const Impl& a) {
  std::vector<int> nodes;
  for (int n : a.scene_nodes) {
    if (a.model.nodes[size_t(n)].mesh >= 0) nodes.push_back(n);
  }
  return nodes;
}

}  // namespace

// === Loading

GltfAsset parse_gltf(const uint8_t* data, size_t size, const std::string& source, const std::string& base_dir) {
  AMT_CHECK(data != nullptr || size == 0, source, ": bytes: expected data, found a null pointer");
  AMT_CHECK(size <= std::numeric_limits<uint32_t>::max(), source, ": size: expected at most 4 GiB, found ", size,
            " bytes");
  const bool is_glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  GlbLayout layout;
  if (is_glb) {
    layout = check_glb(data, size, source);
  } else {
    size_t first = 0;
    if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) first = 3;  // UTF-8 byte order mark
    while (first < size && std::isspace(data[first])) ++first;
    if (first >= size || data[first] != '{') {
      std::ostringstream magic;
      for (size_t i = 0; i < std::min<size_t>(size, 4); ++i) {
        magic << (i ? " " : "") << std::hex << std::setw(2) << std::setfill('0') << int(data[i]);
      }
      fail(source, ": magic: expected a GLB file (magic 'glTF') or glTF JSON (starting with '{'), found ",
           size == 0 ? std::string("an empty file") : "bytes " + magic.str());
    }
    layout.json_size = size;
  }
  check_json(reinterpret_cast<const char*>(data) + layout.json_offset, layout.json_size, is_glb, layout, source,
             base_dir);

  auto impl = std::make_shared<Impl>();
  impl->source = source;
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skip_image, nullptr);
  FileAccess access{base_dir};
  loader.SetFsCallbacks(tinygltf::FsCallbacks{&file_exists, &expand_path, &read_file, &write_file, &access});
  std::string err, warn;
  bool ok = false;
  try {
    if (is_glb) {
      ok = loader.LoadBinaryFromMemory(&impl->model, &err, &warn, data, static_cast<unsigned int>(size), base_dir);
    } else {
      ok = loader.LoadASCIIFromString(&impl->model, &err, &warn, reinterpret_cast<const char*>(data),
                                      static_cast<unsigned int>(size), base_dir);
    }
  } catch (const std::exception& e) {
    fail(source, ": glTF: expected a valid glTF 2.0 asset, found tinygltf error: ", excerpt(e.what(), 200));
  }
  if (!ok) {
    fail(source, ": glTF: expected a valid glTF 2.0 asset, found tinygltf error: ", excerpt(err, 200));
  }
  size_t buffer_bytes = 0;
  for (const tinygltf::Buffer& buffer : impl->model.buffers) buffer_bytes += buffer.data.size();
  impl->value_budget = kBaseValueBudget + kValuesPerBufferByte * buffer_bytes;
  check_nodes(*impl);
  check_meshes_and_skins(*impl);
  read_animations(*impl);
  return GltfAsset(std::move(impl));
}

GltfAsset read_gltf(const std::string& path) {
  check_input_file(path, "a glTF or GLB asset");
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": file: expected a readable glTF or GLB file, found none");
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  AMT_CHECK(!in.bad(), path, ": file: expected a readable glTF or GLB file, found a read error");
  std::string base_dir = std::filesystem::path(path).parent_path().string();
  if (base_dir.empty()) base_dir = ".";
  return parse_gltf(bytes.data(), bytes.size(), path, base_dir);
}

// === Skinned character

GltfCharacter gltf_character(const GltfAsset& asset) {
  const Impl& a = asset.impl();
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;

  // The skin of the first skinned mesh node of the scene (else of the file), and its mesh nodes.
  std::vector<int> candidates = a.scene_nodes;
  int skin = -1;
  for (int pass = 0; pass < 2 && skin < 0; ++pass) {
    for (int n : candidates) {
      if (m.nodes[size_t(n)].mesh >= 0 && m.nodes[size_t(n)].skin >= 0) {
        skin = m.nodes[size_t(n)].skin;
        break;
      }
    }
    if (skin < 0) {
      candidates.resize(m.nodes.size());
      for (size_t n = 0; n < m.nodes.size(); ++n) candidates[n] = int(n);
    }
  }
  AMT_CHECK(skin >= 0, src, ": nodes: expected a node with a mesh and a skin, found none");
  std::vector<int> mesh_nodes;
  for (int n : candidates) {
    if (m.nodes[size_t(n)].mesh >= 0 && m.nodes[size_t(n)].skin == skin) mesh_nodes.push_back(n);
  }

  // Skeleton: the skin's joints, the parent of each being its nearest ancestor node among them.
  const std::vector<int>& joints = m.skins[size_t(skin)].joints;
  const int K = int(joints.size());
  std::map<int, int> skin_index_of_node;
  for (int k = 0; k < K; ++k) skin_index_of_node[joints[size_t(k)]] = k;
  std::vector<int> skin_parent(size_t(K), -1);  // skin joint index of the parent, -1 for roots
  std::vector<int> roots;
  for (int k = 0; k < K; ++k) {
    int p = a.parent[size_t(joints[size_t(k)])];
    while (p >= 0 && !skin_index_of_node.count(p)) p = a.parent[size_t(p)];
    skin_parent[size_t(k)] = p >= 0 ? skin_index_of_node[p] : -1;
    if (p < 0) roots.push_back(k);
  }
  // Several roots: add their nearest common ancestor node (or a scene root at the origin) as root K.
  int added_node = -2;  // -2: none added; -1: "gltf_scene_root"; else a node index
  if (roots.size() > 1) {
    std::vector<int> ancestors;  // of the first root, nearest first
    for (int p = a.parent[size_t(joints[size_t(roots[0])])]; p >= 0; p = a.parent[size_t(p)]) ancestors.push_back(p);
    size_t common = 0;  // position in `ancestors` of the nearest ancestor shared by every root
    for (size_t r = 1; r < roots.size(); ++r) {
      std::unordered_set<int> chain;
      for (int p = a.parent[size_t(joints[size_t(roots[r])])]; p >= 0; p = a.parent[size_t(p)]) chain.insert(p);
      while (common < ancestors.size() && !chain.count(ancestors[common])) ++common;
    }
    added_node = common < ancestors.size() ? ancestors[common] : -1;
    for (int r : roots) skin_parent[size_t(r)] = K;
  }
  const int J = K + (added_node != -2 ? 1 : 0);
  // Topological order (Kahn's algorithm), smallest skin index first: keeps an order that already is.
  std::vector<std::vector<int>> children(static_cast<size_t>(J));
  std::priority_queue<int, std::vector<int>, std::greater<int>> ready;  // skin joint indices
  std::vector<int> order;
  for (int k = 0; k < K; ++k) {
    if (skin_parent[size_t(k)] >= 0) children[size_t(skin_parent[size_t(k)])].push_back(k);
  }
  if (added_node != -2) {
    order.push_back(K);
    for (int c : children[size_t(K)]) ready.push(c);
  } else {
    ready.push(roots[0]);
  }
  while (!ready.empty()) {
    const int k = ready.top();
    ready.pop();
    order.push_back(k);
    for (int c : children[size_t(k)]) ready.push(c);
  }

  GltfCharacter ch;
  ch.skin = skin;
  ch.skin_joint_to_joint.assign(size_t(K), -1);
  std::vector<int> joint_of_id(static_cast<size_t>(J), -1);
  for (int j = 0; j < J; ++j) joint_of_id[size_t(order[size_t(j)])] = j;
  for (int k = 0; k < K; ++k) ch.skin_joint_to_joint[size_t(k)] = joint_of_id[size_t(k)];
  Skeleton& s = ch.skeleton;
  s.rest_joints.resize(J, 3);
  std::set<std::string> taken;
  for (int j = 0; j < J; ++j) {
    const int id = order[size_t(j)];
    const int node = id < K ? joints[size_t(id)] : added_node;
    ch.joint_nodes.push_back(node);
    std::string name = node >= 0 ? m.nodes[size_t(node)].name : "gltf_scene_root";
    if (name.empty()) name = "node_" + std::to_string(node);
    while (taken.count(name)) name += "_" + std::to_string(node);
    taken.insert(name);
    s.names.push_back(name);
    const int parent_id = id < K ? skin_parent[size_t(id)] : -1;
    s.parents.push_back(parent_id >= 0 ? joint_of_id[size_t(parent_id)] : -1);
    const Eigen::Vector3d position =
        node >= 0 ? Eigen::Vector3d(a.rest_world[size_t(node)].topRightCorner<3, 1>()) : Eigen::Vector3d::Zero();
    s.rest_joints.row(j) = position.cast<float>().transpose();
  }
  validate_skeleton(s, src);

  // Mesh: every node of the skin, in the rest pose, with the skin joints' 4 largest weights.
  ValueBudget budget{a.value_budget};
  const Matrices4d ibm = inverse_bind_matrices(a, skin, budget);
  Matrices4d skin_rest(static_cast<size_t>(K));  // G_k(rest) * IBM_k
  for (int k = 0; k < K; ++k) skin_rest[size_t(k)] = a.rest_world[size_t(joints[size_t(k)])] * ibm[size_t(k)];
  const int fallback = first_root_joint(a, skin);
  std::vector<RowsX3d> parts;
  std::vector<int32_t> faces;
  std::vector<int> top_joints;      // #V * 4 skin joint indices, over all mesh nodes
  std::vector<double> top_weights;  // #V * 4 weights
  size_t offset = 0;
  for (int n : mesh_nodes) {
    const MeshGeometry g = read_mesh(a, m.nodes[size_t(n)].mesh, K, fallback, budget);
    // The 4 largest weights per vertex (repeated joints summed), renormalised.
    const size_t V = size_t(g.V.rows());
    MeshGeometry top;
    top.slots = kMaxInfluences;
    top.joints.assign(V * kMaxInfluences, 0);
    top.weights.assign(V * kMaxInfluences, 0.0);
    for (size_t i = 0; i < V; ++i) {
      std::map<int, double> by_joint;
      for (int slot = 0; slot < g.slots; ++slot) {
        const double w = g.weights[i * size_t(g.slots) + size_t(slot)];
        if (w > 0.0) by_joint[g.joints[i * size_t(g.slots) + size_t(slot)]] += w;
      }
      std::vector<std::pair<int, double>> sorted(by_joint.begin(), by_joint.end());
      std::stable_sort(sorted.begin(), sorted.end(), [](const auto& x, const auto& y) { return x.second > y.second; });
      sorted.resize(std::min<size_t>(sorted.size(), kMaxInfluences));
      double sum = 0.0;
      for (const auto& jw : sorted) sum += jw.second;
      for (size_t slot = 0; slot < sorted.size(); ++slot) {
        top.joints[i * kMaxInfluences + slot] = sorted[slot].first;
        top.weights[i * kMaxInfluences + slot] = sorted[slot].second / sum;
      }
    }
    parts.push_back(skin_positions(top, morphed(g, node_weights(a, nullptr, 0.0, n)), skin_rest));
    for (int32_t f : g.faces) faces.push_back(int32_t(offset) + f);
    top_joints.insert(top_joints.end(), top.joints.begin(), top.joints.end());
    top_weights.insert(top_weights.end(), top.weights.begin(), top.weights.end());
    offset += V;
  }
  ch.mesh.V.resize(Eigen::Index(offset), 3);
  Eigen::Index row = 0;
  for (const RowsX3d& P : parts) {
    ch.mesh.V.middleRows(row, P.rows()) = P.cast<float>();
    row += P.rows();
  }
  ch.mesh.F.resize(Eigen::Index(faces.size() / 3), 3);
  std::copy(faces.begin(), faces.end(), ch.mesh.F.data());
  validate_mesh(ch.mesh, src);
  ch.weights.indices.setZero(Eigen::Index(offset), kMaxInfluences);
  ch.weights.weights.setZero(Eigen::Index(offset), kMaxInfluences);
  for (size_t i = 0; i < offset; ++i) {
    for (int slot = 0; slot < kMaxInfluences; ++slot) {
      const double w = top_weights[i * kMaxInfluences + size_t(slot)];
      if (w == 0.0) continue;
      ch.weights.indices(Eigen::Index(i), slot) =
          ch.skin_joint_to_joint[size_t(top_joints[i * kMaxInfluences + size_t(slot)])];
      ch.weights.weights(Eigen::Index(i), slot) = float(w);
    }
  }
  return ch;
}

// === Animation

GltfMotion gltf_motion(const GltfAsset& asset, const GltfCharacter& character, const std::string& clip_name,
                       float fps) {
  const Impl& a = asset.impl();
  const std::string& src = a.source;
  const Skeleton& s = character.skeleton;
  const int J = s.num_joints();
  AMT_CHECK(int(character.joint_nodes.size()) == J && J > 0, src, ": character: expected one node per joint (", J,
            "), found ", character.joint_nodes.size());
  for (int node : character.joint_nodes) {
    AMT_CHECK(node >= -1 && node < int(a.model.nodes.size()), src, ": character: expected joint node indices in ",
              "[0, ", a.model.nodes.size(), "), found ", node);
  }
  const Clip* clip = find_clip(a, clip_name);
  const int T = frame_count(a, clip, fps);

  // L(W_n(rest))^-1 per joint.
  std::vector<Eigen::Matrix3d, Eigen::aligned_allocator<Eigen::Matrix3d>> rest_inverse(size_t(J),
                                                                                       Eigen::Matrix3d::Identity());
  for (int j = 0; j < J; ++j) {
    const int node = character.joint_nodes[size_t(j)];
    if (node < 0) continue;
    const Eigen::Matrix3d L = a.rest_world[size_t(node)].topLeftCorner<3, 3>();
    const double det = L.determinant();
    AMT_CHECK(std::abs(det) > 1e-12 * std::pow(std::max(L.norm(), 1e-30), 3), src, ": nodes[", node,
              "]: expected an invertible global rest transform for joint '", s.names[size_t(j)],
              "', found determinant ", det);
    rest_inverse[size_t(j)] = L.inverse();
  }

  GltfMotion out;
  out.clip = clip ? clip->name : "";
  out.start = clip ? float(clip->start) : 0.0f;
  out.duration = clip ? float(clip->end - clip->start) : 0.0f;
  Motion& motion = out.motion;
  motion = rest_motion(s, T, fps);
  Pose pose;
  std::vector<Eigen::Quaterniond> global(static_cast<size_t>(J));
  std::vector<Eigen::Vector3d> positions(static_cast<size_t>(T) * size_t(J));
  for (int t = 0; t < T; ++t) {
    const double time = (clip ? clip->start : 0.0) + double(t) / fps;
    evaluate_pose(a, clip, time, pose);
    for (int j = 0; j < J; ++j) {
      const int node = character.joint_nodes[size_t(j)];
      if (node < 0) {
        global[size_t(j)] = Eigen::Quaterniond::Identity();
        positions[size_t(t) * size_t(J) + size_t(j)] = Eigen::Vector3d::Zero();
        continue;
      }
      const Eigen::Matrix4d& W = pose.world[size_t(node)];
      const Eigen::Matrix3d R = nearest_rotation(W.topLeftCorner<3, 3>() * rest_inverse[size_t(j)]);
      global[size_t(j)] = Eigen::Quaterniond(R).normalized();
      positions[size_t(t) * size_t(J) + size_t(j)] = W.topRightCorner<3, 1>();
    }
    for (int j = 0; j < J; ++j) {
      const int p = s.parents[size_t(j)];
      Eigen::Quaterniond local = p < 0 ? global[size_t(j)] : global[size_t(p)].conjugate() * global[size_t(j)];
      local.normalize();
      // Keep each joint's quaternions in one hemisphere over time (w >= 0 at frame 0).
      const Eigen::Quaternionf previous = t > 0 ? motion.rotation(t - 1, j) : Eigen::Quaternionf::Identity();
      Eigen::Quaternionf q = local.cast<float>();
      if (q.coeffs().dot(previous.coeffs()) < 0.0f) q.coeffs() = -q.coeffs();
      motion.rotation(t, j) = q;
    }
  }

  // Root translation: the skin-weighted mean of what forward kinematics without it leaves between each
  // joint and its glTF position (see GltfMotion). Skin weight per joint, over all vertices:
  std::vector<double> mass(static_cast<size_t>(J), 0.0);
  for (int i = 0; i < character.weights.num_vertices(); ++i) {
    for (int slot = 0; slot < kMaxInfluences; ++slot) {
      const int j = character.weights.indices(i, slot);
      AMT_CHECK(j >= 0 && j < J, src, ": character: expected weight joint indices in [0, ", J, "), found ", j);
      mass[size_t(j)] += std::max(0.0f, character.weights.weights(i, slot));
    }
  }
  double total_mass = 0.0;
  for (double w : mass) total_mass += w;
  if (total_mass <= 0.0) {
    mass.assign(mass.size(), 0.0);
    mass[0] = total_mass = 1.0;  // no weights: the root joint itself
  }
  for (int t = 0; t < T; ++t) {
    const Transforms fk = forward_kinematics(s, motion, t);  // root_translation(t) is still 0
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j = 0; j < J; ++j) {
      if (mass[size_t(j)] == 0.0) continue;
      mean += mass[size_t(j)] * (positions[size_t(t) * size_t(J) + size_t(j)] - fk[size_t(j)].col(3).cast<double>());
    }
    motion.root_translation.row(t) = (mean / total_mass).cast<float>().transpose();
  }
  validate_motion(motion, s, src);

  double error = 0.0, skinned_error = 0.0;
  for (int t = 0; t < T; ++t) {
    const Transforms fk = forward_kinematics(s, motion, t);
    for (int j = 0; j < J; ++j) {
      const Eigen::Vector3d p = fk[size_t(j)].col(3).cast<double>();
      const double e = (p - positions[size_t(t) * size_t(J) + size_t(j)]).norm();
      error = std::max(error, e);
      if (mass[size_t(j)] > 0.0) skinned_error = std::max(skinned_error, e);
    }
  }
  out.joint_position_error = float(error);
  out.skinned_joint_position_error = float(skinned_error);
  return out;
}

GltfVertexAnimation gltf_vertex_animation(const GltfAsset& asset, const std::string& clip_name, float fps) {
  const Impl& a = asset.impl();
  const tinygltf::Model& m = a.model;
  const std::string& src = a.source;
  const Clip* clip = find_clip(a, clip_name);
  const int T = frame_count(a, clip, fps);

  // Per mesh node: geometry and, when skinned, the skin's joints and inverse bind matrices.
  struct NodeMesh {
    int node = -1;
    int skin = -1;
    MeshGeometry geometry;
    Matrices4d ibm;
    size_t offset = 0;
  };
  std::vector<NodeMesh> meshes;
  std::vector<int32_t> faces;
  size_t total = 0;
  ValueBudget budget{a.value_budget};
  for (int n : scene_mesh_nodes(a)) {
    NodeMesh nm;
    nm.node = n;
    nm.skin = m.nodes[size_t(n)].skin;
    const int K = nm.skin >= 0 ? int(m.skins[size_t(nm.skin)].joints.size()) : 0;
    nm.geometry = read_mesh(a, m.nodes[size_t(n)].mesh, K, nm.skin >= 0 ? first_root_joint(a, nm.skin) : 0, budget);
    if (nm.skin >= 0) nm.ibm = inverse_bind_matrices(a, nm.skin, budget);
    nm.offset = total;
    for (int32_t f : nm.geometry.faces) faces.push_back(int32_t(total) + f);
    total += size_t(nm.geometry.V.rows());
    meshes.push_back(std::move(nm));
  }
  AMT_CHECK(total > 0 && !faces.empty(), src, ": meshes: expected a mesh node with triangles in the scene, found none");
  AMT_CHECK(size_t(T) <= kMaxAnimatedVertices / total, src, ": animation: expected at most ", kMaxAnimatedVertices,
            " frames x vertices, found ", T, " x ", total);

  GltfVertexAnimation out;
  out.clip = clip ? clip->name : "";
  out.start = clip ? float(clip->start) : 0.0f;
  out.duration = clip ? float(clip->end - clip->start) : 0.0f;
  out.fps = fps;
  out.faces.resize(Eigen::Index(faces.size() / 3), 3);
  std::copy(faces.begin(), faces.end(), out.faces.data());
  Pose pose;
  for (int t = 0; t < T; ++t) {
    const double time = (clip ? clip->start : 0.0) + double(t) / fps;
    evaluate_pose(a, clip, time, pose);
    MatrixX3f frame(Eigen::Index(total), 3);
    for (const NodeMesh& nm : meshes) {
      const RowsX3d P = morphed(nm.geometry, node_weights(a, clip, time, nm.node));
      RowsX3d Q;
      if (nm.skin >= 0) {
        const std::vector<int>& joints = m.skins[size_t(nm.skin)].joints;
        Matrices4d M(joints.size());
        for (size_t k = 0; k < joints.size(); ++k) M[k] = pose.world[size_t(joints[k])] * nm.ibm[k];
        Q = skin_positions(nm.geometry, P, M);
      } else {
        const Eigen::Matrix4d& W = pose.world[size_t(nm.node)];
        Q = (P * W.topLeftCorner<3, 3>().transpose()).rowwise() + W.topRightCorner<3, 1>().transpose();
      }
      frame.middleRows(Eigen::Index(nm.offset), Q.rows()) = Q.cast<float>();
    }
    AMT_CHECK(frame.allFinite(), src, ": animation \"", out.clip, "\": expected finite vertex positions, found NaN ",
              "or infinity at frame ", t);
    if (t == 0) check_plausible_extent(TriMesh{frame, out.faces}, src + ": animation \"" + out.clip + "\" frame 0");
    out.frames.push_back(std::move(frame));
  }
  return out;
}

// === VRM avatars

namespace {

// The extension `name` of the asset's top level, or null.
const tinygltf::Value* top_extension(const tinygltf::Model& m, const char* name) {
  const auto it = m.extensions.find(name);
  return it == m.extensions.end() || !it->second.IsObject() ? nullptr : &it->second;
}

// A node index held in `value` (field `field`), checked against the file's nodes.
int vrm_node(const tinygltf::Value& value, const tinygltf::Model& m, const std::string& src, const std::string& field) {
  AMT_CHECK(value.IsNumber(), src, ": ", field, ": expected a node index, found ",
            value.IsString()   ? "a string"
            : value.IsObject() ? "an object"
                               : "another type");
  const double n = value.GetNumberAsDouble();
  AMT_CHECK(n >= 0 && n < double(m.nodes.size()) && n == std::floor(n), src, ": ", field,
            ": expected a node index in [0, ", m.nodes.size(), "), found ", n);
  return int(n);
}

// Per skeleton joint of `character`, keyed by its node.
std::map<int, int> joint_of_node(const GltfCharacter& character) {
  std::map<int, int> out;
  for (size_t j = 0; j < character.joint_nodes.size(); ++j) {
    if (character.joint_nodes[j] >= 0) out[character.joint_nodes[j]] = int(j);
  }
  return out;
}

}  // namespace

std::string gltf_vrm_version(const GltfAsset& asset) {
  const tinygltf::Model& m = asset.impl().model;
  if (top_extension(m, "VRMC_vrm")) return "1";
  if (top_extension(m, "VRM")) return "0";
  return "";
}

std::optional<JointMapFile> gltf_vrm_joint_map(const GltfAsset& asset, const GltfCharacter& character) {
  const tinygltf::Model& m = asset.impl().model;
  const std::string& src = asset.source();
  // VRM humanoid bone -> canonical joint; the spine, chest and upper chest come from the structure.
  static const std::map<std::string, std::string> kCanonical = {{"hips", "pelvis"},
                                                                {"leftUpperLeg", "left_hip"},
                                                                {"rightUpperLeg", "right_hip"},
                                                                {"leftLowerLeg", "left_knee"},
                                                                {"rightLowerLeg", "right_knee"},
                                                                {"leftFoot", "left_ankle"},
                                                                {"rightFoot", "right_ankle"},
                                                                {"leftToes", "left_foot"},
                                                                {"rightToes", "right_foot"},
                                                                {"neck", "neck"},
                                                                {"head", "head"},
                                                                {"leftShoulder", "left_collar"},
                                                                {"rightShoulder", "right_collar"},
                                                                {"leftUpperArm", "left_shoulder"},
                                                                {"rightUpperArm", "right_shoulder"},
                                                                {"leftLowerArm", "left_elbow"},
                                                                {"rightLowerArm", "right_elbow"},
                                                                {"leftHand", "left_wrist"},
                                                                {"rightHand", "right_wrist"}};
  std::vector<std::pair<std::string, int>> bones;  // (VRM bone, node)
  std::string base;
  if (const tinygltf::Value* vrm1 = top_extension(m, "VRMC_vrm")) {
    base = "extensions.VRMC_vrm.humanoid.humanBones";
    const tinygltf::Value& humanoid = vrm1->Get("humanoid");
    const tinygltf::Value& human = humanoid.Get("humanBones");
    AMT_CHECK(human.IsObject(), src, ": ", base, ": expected an object {bone: {node}}, found ",
              human.Type() == tinygltf::NULL_TYPE ? "none" : "another type");
    for (const std::string& bone : human.Keys()) {
      const tinygltf::Value& entry = human.Get(bone);
      AMT_CHECK(entry.IsObject() && entry.Has("node"), src, ": ", base, ".", bone, ".node: expected a node index, ",
                "found none");
      bones.emplace_back(bone, vrm_node(entry.Get("node"), m, src, base + "." + bone + ".node"));
    }
  } else if (const tinygltf::Value* vrm0 = top_extension(m, "VRM")) {
    base = "extensions.VRM.humanoid.humanBones";
    const tinygltf::Value& human = vrm0->Get("humanoid").Get("humanBones");
    AMT_CHECK(human.IsArray(), src, ": ", base, ": expected an array of {bone, node}, found ",
              human.Type() == tinygltf::NULL_TYPE ? "none" : "another type");
    for (size_t k = 0; k < human.ArrayLen(); ++k) {
      const tinygltf::Value& entry = human.Get(int(k));
      const std::string field = base + "[" + std::to_string(k) + "]";
      AMT_CHECK(entry.IsObject() && entry.Get("bone").IsString(), src, ": ", field,
                ".bone: expected a humanoid bone name, found none");
      bones.emplace_back(entry.Get("bone").Get<std::string>(), vrm_node(entry.Get("node"), m, src, field + ".node"));
    }
  } else {
    return std::nullopt;
  }
  const std::map<int, int> joint = joint_of_node(character);
  JointMapFile map;
  map.source = src + " (VRM humanoid)";
  const std::vector<std::string>& names = canonical_joint_names();
  for (const auto& [bone, node] : bones) {
    const auto canonical = kCanonical.find(bone);
    const auto j = joint.find(node);
    if (canonical == kCanonical.end() || j == joint.end()) continue;
    const int index = int(std::find(names.begin(), names.end(), canonical->second) - names.begin());
    map.entries.emplace_back(index, character.skeleton.names[size_t(j->second)]);
  }
  return map;
}

std::vector<uint8_t> gltf_vrm_spring_joints(const GltfAsset& asset, const GltfCharacter& character) {
  const tinygltf::Model& m = asset.impl().model;
  const std::string& src = asset.source();
  std::vector<int> roots;  // nodes a spring moves, with everything below them
  if (const tinygltf::Value* spring = top_extension(m, "VRMC_springBone")) {
    const tinygltf::Value& springs = spring->Get("springs");
    for (size_t s = 0; springs.IsArray() && s < springs.ArrayLen(); ++s) {
      const tinygltf::Value& joints = springs.Get(int(s)).Get("joints");
      for (size_t k = 0; joints.IsArray() && k < joints.ArrayLen(); ++k) {
        const std::string field =
            "extensions.VRMC_springBone.springs[" + std::to_string(s) + "].joints[" + std::to_string(k) + "].node";
        roots.push_back(vrm_node(joints.Get(int(k)).Get("node"), m, src, field));
      }
    }
  } else if (const tinygltf::Value* vrm0 = top_extension(m, "VRM")) {
    const tinygltf::Value& groups = vrm0->Get("secondaryAnimation").Get("boneGroups");
    for (size_t g = 0; groups.IsArray() && g < groups.ArrayLen(); ++g) {
      const tinygltf::Value& list = groups.Get(int(g)).Get("bones");
      for (size_t k = 0; list.IsArray() && k < list.ArrayLen(); ++k) {
        const std::string field =
            "extensions.VRM.secondaryAnimation.boneGroups[" + std::to_string(g) + "].bones[" + std::to_string(k) + "]";
        roots.push_back(vrm_node(list.Get(int(k)), m, src, field));
      }
    }
  }
  if (roots.empty()) return {};
  // A node is moved when it or an ancestor is a spring's.
  const Impl& a = asset.impl();
  std::vector<uint8_t> moved_node(m.nodes.size(), 0);
  for (int r : roots) moved_node[size_t(r)] = 1;
  for (int n : a.node_order) {  // parents first
    const int p = a.parent[size_t(n)];
    if (p >= 0 && moved_node[size_t(p)]) moved_node[size_t(n)] = 1;
  }
  std::vector<uint8_t> out(character.joint_nodes.size(), 0);
  for (size_t j = 0; j < out.size(); ++j) {
    const int n = character.joint_nodes[j];
    out[j] = n >= 0 && moved_node[size_t(n)];
  }
  return out;
}

// === VRM spring bones

namespace {

float number_or(const tinygltf::Value& object, const char* key, float fallback, const std::string& src,
                const std::string& field) {
  if (!object.IsObject() || !object.Has(key)) return fallback;
  const tinygltf::Value& v = object.Get(key);
  AMT_CHECK(v.IsNumber(), src, ": ", field, ".", key, ": expected a number, found another type");
  const double x = v.GetNumberAsDouble();
  AMT_CHECK(std::isfinite(x), src, ": ", field, ".", key, ": expected a finite number, found ", x);
  return float(x);
}

// A vector given as [x, y, z] (VRM 1.0) or {x, y, z} (VRM 0.x).
Eigen::Vector3f vector_or(const tinygltf::Value& object, const char* key, const Eigen::Vector3f& fallback,
                          const std::string& src, const std::string& field) {
  if (!object.IsObject() || !object.Has(key)) return fallback;
  const tinygltf::Value& v = object.Get(key);
  Eigen::Vector3f out = fallback;
  if (v.IsArray()) {
    AMT_CHECK(v.ArrayLen() == 3, src, ": ", field, ".", key, ": expected 3 numbers, found ", v.ArrayLen());
    for (int i = 0; i < 3; ++i) {
      AMT_CHECK(v.Get(i).IsNumber(), src, ": ", field, ".", key, "[", i, "]: expected a number");
      out[i] = float(v.Get(i).GetNumberAsDouble());
    }
  } else {
    AMT_CHECK(v.IsObject(), src, ": ", field, ".", key, ": expected [x, y, z] or {x, y, z}, found another type");
    const char* axes[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i) out[i] = number_or(v, axes[i], fallback[i], src, field + "." + key);
  }
  AMT_CHECK(out.allFinite(), src, ": ", field, ".", key, ": expected finite numbers");
  return out;
}

Eigen::Vector3f rest_point(const GltfAsset::Impl& a, int node, const Eigen::Vector3f& local = Eigen::Vector3f::Zero()) {
  const Eigen::Vector4d p = a.rest_world[size_t(node)] * Eigen::Vector4d(local.x(), local.y(), local.z(), 1.0);
  return p.head<3>().cast<float>();
}

}  // namespace

SpringRig gltf_vrm_spring_rig(const GltfAsset& asset, const GltfCharacter& character) {
  const GltfAsset::Impl& a = asset.impl();
  const tinygltf::Model& m = a.model;
  const std::string& src = asset.source();
  const std::map<int, int> joints = joint_of_node(character);
  SpringRig rig;
  // The joint that carries a node: its own, else its nearest ancestor's (-1 when none is a joint).
  const auto carrier = [&](int node) {
    for (int n = node; n >= 0; n = a.parent[size_t(n)]) {
      const auto it = joints.find(n);
      if (it != joints.end()) return it->second;
    }
    return -1;
  };
  std::vector<uint8_t> taken(character.joint_nodes.size(), 0);
  int unskinned = 0, repeated = 0;
  const auto add = [&](int node, const Eigen::Vector3f& tail, SpringJoint joint) {
    const auto it = joints.find(node);
    if (it == joints.end()) return void(++unskinned);
    if (taken[size_t(it->second)]) return void(++repeated);
    taken[size_t(it->second)] = 1;
    joint.joint = it->second;
    joint.tail = tail;
    if (joint.gravity_dir.norm() > 0.0f) joint.gravity_dir.normalize();
    const Eigen::Vector3f head = character.skeleton.rest_joints.row(joint.joint).transpose();
    if ((tail - head).norm() > 1e-6f) rig.joints.push_back(joint);
  };
  int centres = 0;
  if (const tinygltf::Value* ext = top_extension(m, "VRMC_springBone")) {
    const std::string base = "extensions.VRMC_springBone";
    const tinygltf::Value& colliders = ext->Get("colliders");
    std::vector<int> collider_index;  // per file collider, its index in rig.colliders or -1
    for (size_t c = 0; colliders.IsArray() && c < colliders.ArrayLen(); ++c) {
      const std::string field = base + ".colliders[" + std::to_string(c) + "]";
      const tinygltf::Value& col = colliders.Get(int(c));
      const int node = vrm_node(col.Get("node"), m, src, field + ".node");
      const tinygltf::Value& shape = col.Get("shape");
      SpringCollider k;
      k.joint = carrier(node);
      const bool sphere = shape.Has("sphere"), capsule = shape.Has("capsule");
      if (k.joint < 0 || (!sphere && !capsule)) {
        collider_index.push_back(-1);
        continue;
      }
      const tinygltf::Value& s = shape.Get(sphere ? "sphere" : "capsule");
      const std::string f = field + ".shape." + (sphere ? "sphere" : "capsule");
      k.center = rest_point(a, node, vector_or(s, "offset", Eigen::Vector3f::Zero(), src, f));
      k.radius = number_or(s, "radius", 0.0f, src, f);
      k.capsule = capsule && !sphere;
      k.tail = k.capsule ? rest_point(a, node, vector_or(s, "tail", Eigen::Vector3f::Zero(), src, f)) : k.center;
      AMT_CHECK(k.radius >= 0.0f && k.radius < 100.0f, src, ": ", f, ".radius: expected [0, 100) metres, found ",
                k.radius);
      collider_index.push_back(int(rig.colliders.size()));
      rig.colliders.push_back(k);
    }
    const tinygltf::Value& groups = ext->Get("colliderGroups");
    const tinygltf::Value& springs = ext->Get("springs");
    for (size_t s = 0; springs.IsArray() && s < springs.ArrayLen(); ++s) {
      const std::string field = base + ".springs[" + std::to_string(s) + "]";
      const tinygltf::Value& spring = springs.Get(int(s));
      if (spring.Has("center")) ++centres;
      std::vector<int> list;
      const tinygltf::Value& own = spring.Get("colliderGroups");
      for (size_t g = 0; own.IsArray() && g < own.ArrayLen(); ++g) {
        const tinygltf::Value& gi = own.Get(int(g));
        AMT_CHECK(gi.IsNumber() && gi.GetNumberAsDouble() >= 0 && gi.GetNumberAsDouble() < double(groups.ArrayLen()),
                  src, ": ", field, ".colliderGroups[", g, "]: expected a collider group index in [0, ",
                  groups.IsArray() ? groups.ArrayLen() : 0, ")");
        const tinygltf::Value& members = groups.Get(int(gi.GetNumberAsDouble())).Get("colliders");
        for (size_t k = 0; members.IsArray() && k < members.ArrayLen(); ++k) {
          const tinygltf::Value& ci = members.Get(int(k));
          AMT_CHECK(
              ci.IsNumber() && ci.GetNumberAsDouble() >= 0 && ci.GetNumberAsDouble() < double(collider_index.size()),
              src, ": ", base, ".colliderGroups[", int(gi.GetNumberAsDouble()), "].colliders[", k,
              "]: expected a collider index in [0, ", collider_index.size(), ")");
          const int c = collider_index[size_t(ci.GetNumberAsDouble())];
          if (c >= 0 && std::find(list.begin(), list.end(), c) == list.end()) list.push_back(c);
        }
      }
      const int index = int(rig.spring_colliders.size());
      rig.spring_colliders.push_back(list);
      // A spring's joints in order: each joint's segment ends at the next joint (the last has none).
      const tinygltf::Value& js = spring.Get("joints");
      for (size_t k = 0; js.IsArray() && k + 1 < js.ArrayLen(); ++k) {
        const std::string f = field + ".joints[" + std::to_string(k) + "]";
        const tinygltf::Value& j = js.Get(int(k));
        const int node = vrm_node(j.Get("node"), m, src, f + ".node");
        const int next =
            vrm_node(js.Get(int(k + 1)).Get("node"), m, src, field + ".joints[" + std::to_string(k + 1) + "].node");
        SpringJoint sj;
        sj.spring = index;
        sj.hit_radius = number_or(j, "hitRadius", 0.0f, src, f);
        sj.stiffness = number_or(j, "stiffness", 1.0f, src, f);
        sj.gravity_power = number_or(j, "gravityPower", 0.0f, src, f);
        sj.gravity_dir = vector_or(j, "gravityDir", Eigen::Vector3f(0, -1, 0), src, f);
        sj.drag = number_or(j, "dragForce", 0.5f, src, f);
        add(node, rest_point(a, next), sj);
      }
    }
  } else if (const tinygltf::Value* vrm0 = top_extension(m, "VRM")) {
    const std::string base = "extensions.VRM.secondaryAnimation";
    const tinygltf::Value& secondary = vrm0->Get("secondaryAnimation");
    const tinygltf::Value& groups = secondary.Get("colliderGroups");
    std::vector<std::vector<int>> group_colliders;
    for (size_t g = 0; groups.IsArray() && g < groups.ArrayLen(); ++g) {
      const std::string field = base + ".colliderGroups[" + std::to_string(g) + "]";
      const tinygltf::Value& group = groups.Get(int(g));
      const int node = vrm_node(group.Get("node"), m, src, field + ".node");
      std::vector<int> list;
      const tinygltf::Value& cs = group.Get("colliders");
      for (size_t c = 0; cs.IsArray() && c < cs.ArrayLen(); ++c) {
        const std::string f = field + ".colliders[" + std::to_string(c) + "]";
        SpringCollider k;
        k.joint = carrier(node);
        if (k.joint < 0) continue;
        Eigen::Vector3f offset = vector_or(cs.Get(int(c)), "offset", Eigen::Vector3f::Zero(), src, f);
        offset.z() = -offset.z();  // VRM 0.x writes collider offsets with z mirrored (Unity's left-handed axes)
        k.center = k.tail = rest_point(a, node, offset);
        k.radius = number_or(cs.Get(int(c)), "radius", 0.0f, src, f);
        AMT_CHECK(k.radius >= 0.0f && k.radius < 100.0f, src, ": ", f, ".radius: expected [0, 100) metres, found ",
                  k.radius);
        list.push_back(int(rig.colliders.size()));
        rig.colliders.push_back(k);
      }
      group_colliders.push_back(list);
    }
    const tinygltf::Value& bone_groups = secondary.Get("boneGroups");
    int branches = 0;
    for (size_t g = 0; bone_groups.IsArray() && g < bone_groups.ArrayLen(); ++g) {
      const std::string field = base + ".boneGroups[" + std::to_string(g) + "]";
      const tinygltf::Value& group = bone_groups.Get(int(g));
      if (group.Has("center") && group.Get("center").IsNumber() && group.Get("center").GetNumberAsDouble() >= 0)
        ++centres;
      SpringJoint sj;
      sj.spring = int(rig.spring_colliders.size());
      sj.stiffness = number_or(group, "stiffiness", 1.0f, src, field);  // sic: VRM 0.x spells it so
      sj.gravity_power = number_or(group, "gravityPower", 0.0f, src, field);
      sj.gravity_dir = vector_or(group, "gravityDir", Eigen::Vector3f(0, -1, 0), src, field);
      sj.drag = number_or(group, "dragForce", 0.4f, src, field);
      sj.hit_radius = number_or(group, "hitRadius", 0.02f, src, field);
      std::vector<int> list;
      const tinygltf::Value& own = group.Get("colliderGroups");
      for (size_t k = 0; own.IsArray() && k < own.ArrayLen(); ++k) {
        const tinygltf::Value& gi = own.Get(int(k));
        AMT_CHECK(
            gi.IsNumber() && gi.GetNumberAsDouble() >= 0 && gi.GetNumberAsDouble() < double(group_colliders.size()),
            src, ": ", field, ".colliderGroups[", k, "]: expected a collider group index in [0, ",
            group_colliders.size(), ")");
        for (int c : group_colliders[size_t(gi.GetNumberAsDouble())]) list.push_back(c);
      }
      rig.spring_colliders.push_back(list);
      // Every node under each root is a segment whose tail is its first child, or, for a leaf, a point 7 cm on
      // along its bone from its parent (UniVRM's VRMSpringBone.SetupRecursive, three-vrm's loader).
      const tinygltf::Value& roots = group.Get("bones");
      for (size_t r = 0; roots.IsArray() && r < roots.ArrayLen(); ++r) {
        const int root = vrm_node(roots.Get(int(r)), m, src, field + ".bones[" + std::to_string(r) + "]");
        std::vector<int> stack{root};
        while (!stack.empty()) {
          const int n = stack.back();
          stack.pop_back();
          const auto& children = m.nodes[size_t(n)].children;
          if (children.size() > 1) ++branches;
          const Eigen::Vector3f head = rest_point(a, n);
          Eigen::Vector3f tail;
          if (!children.empty()) {
            tail = rest_point(a, children[0]);
          } else {
            const int p = a.parent[size_t(n)];
            const Eigen::Vector3f along = p >= 0 ? Eigen::Vector3f(head - rest_point(a, p)) : Eigen::Vector3f::Zero();
            tail =
                head + (along.norm() > 1e-9f ? Eigen::Vector3f(along.normalized()) : Eigen::Vector3f(0, -1, 0)) * 0.07f;
          }
          add(n, tail, sj);
          for (auto c = children.rbegin(); c != children.rend(); ++c) stack.push_back(*c);
        }
      }
    }
    if (branches > 0)
      rig.notes.push_back(std::to_string(branches) +
                          " spring node(s) branch: each takes its first child as its tail, as UniVRM does");
  }
  if (centres > 0)
    rig.notes.push_back(std::to_string(centres) + " spring(s) name a centre node: simulated in world space instead");
  if (unskinned > 0)
    rig.notes.push_back(std::to_string(unskinned) +
                        " spring node(s) move no vertex (not joints of the skin): left out");
  if (repeated > 0)
    rig.notes.push_back(std::to_string(repeated) + " spring node(s) listed twice: the first listing kept");
  std::sort(rig.joints.begin(), rig.joints.end(),
            [](const SpringJoint& x, const SpringJoint& y) { return x.joint < y.joint; });
  validate_spring_rig(rig, character.skeleton, src);
  return rig;
}

}  // namespace amt

// === Writing an asset back with an animation

namespace amt {

void export_gltf_animated_copy(const GltfAsset& source, const GltfCharacter& character,
                               const std::vector<Transforms>& frames, float fps, const std::string& clip,
                               const std::string& path) {
  const GltfAsset::Impl& a = source.impl();
  const int J = character.skeleton.num_joints();
  const size_t N = a.model.nodes.size();
  AMT_CHECK(!frames.empty(), path, ": frames: expected at least one frame, found none");
  AMT_CHECK(std::isfinite(fps) && fps > 0.0f, path, ": fps: expected a positive frame rate, found ", fps);
  AMT_CHECK(int(character.joint_nodes.size()) == J, path, ": character: expected one node per joint (", J, "), found ",
            character.joint_nodes.size());
  std::vector<int> joint_of_node(N, -1);
  for (int j = 0; j < J; ++j) {
    const int n = character.joint_nodes[size_t(j)];
    if (n >= 0 && size_t(n) < N) joint_of_node[size_t(n)] = j;
  }
  AMT_CHECK(a.model.buffers.size() <= 1, path, ": expected an asset with one buffer (a .glb or .vrm), found ",
            a.model.buffers.size(), " buffers");
  tinygltf::Model model = a.model;
  model.animations.clear();
  GltfBuffer buffer(model);
  auto add_accessor = [&](const std::vector<float>& values, int type, int components, bool bounds) {
    return buffer.accessor(values, TINYGLTF_COMPONENT_TYPE_FLOAT, type, components, 0, bounds);
  };
  // Per frame, every node's global transform: a joint's is its skinning transform times its rest global transform,
  // any other node keeps its rest place under its parent; each animated node's local transform follows.
  const size_t T = frames.size();
  std::vector<std::vector<float>> rotations(N), translations(N);
  Matrices4d world(N);
  for (size_t t = 0; t < T; ++t) {
    AMT_CHECK(frames[t].size() == size_t(J), path, ": frame ", t, ": expected ", J, " transforms, found ",
              frames[t].size());
    for (const int n : a.node_order) {
      const int p = a.parent[size_t(n)];
      const int j = joint_of_node[size_t(n)];
      if (j >= 0) {
        Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
        M.topRows<3>() = frames[t][size_t(j)].cast<double>();
        AMT_CHECK(M.allFinite(), path, ": frame ", t, ": expected finite transforms, found one at joint ",
                  character.skeleton.names[size_t(j)]);
        world[size_t(n)] = M * a.rest_world[size_t(n)];
        const Eigen::Matrix4d local =
            p < 0 ? world[size_t(n)] : Eigen::Matrix4d(world[size_t(p)].inverse() * world[size_t(n)]);
        // The rotation of the local matrix (its rest scale divided out by the polar decomposition).
        const Eigen::JacobiSVD<Eigen::Matrix3d> svd(local.topLeftCorner<3, 3>(),
                                                    Eigen::ComputeFullU | Eigen::ComputeFullV);
        Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
        if (R.determinant() < 0) R = -R;
        const Eigen::Quaterniond q(R);
        for (const double c : {q.x(), q.y(), q.z(), q.w()}) rotations[size_t(n)].push_back(float(c));
        for (int c = 0; c < 3; ++c) translations[size_t(n)].push_back(float(local(c, 3)));
      } else {
        const NodeRest& r = a.rest[size_t(n)];
        const Eigen::Matrix4d local = r.has_matrix ? r.matrix : trs_matrix(r.translation, r.rotation, r.scale);
        world[size_t(n)] = p < 0 ? local : Eigen::Matrix4d(world[size_t(p)] * local);
      }
    }
  }
  std::vector<float> times(T);
  for (size_t t = 0; t < T; ++t) times[t] = float(double(t) / double(fps));
  tinygltf::Animation animation;
  animation.name = clip;
  const int input = add_accessor(times, TINYGLTF_TYPE_SCALAR, 1, true);
  for (size_t n = 0; n < N; ++n) {
    if (joint_of_node[n] < 0) continue;
    AMT_CHECK(!a.rest[n].has_matrix, path, ": node ", n, " (", a.model.nodes[n].name, "): expected a joint with ",
              "translation, rotation and scale, found a matrix, which glTF does not animate");
    for (const auto& [values, type, components, target] :
         {std::tuple{&rotations[n], TINYGLTF_TYPE_VEC4, 4, "rotation"},
          std::tuple{&translations[n], TINYGLTF_TYPE_VEC3, 3, "translation"}}) {
      tinygltf::AnimationSampler sampler;
      sampler.input = input;
      sampler.output = add_accessor(*values, type, components, false);
      sampler.interpolation = "LINEAR";
      animation.samplers.push_back(sampler);
      tinygltf::AnimationChannel channel;
      channel.sampler = int(animation.samplers.size()) - 1;
      channel.target_node = int(n);
      channel.target_path = target;
      animation.channels.push_back(channel);
    }
  }
  model.animations.push_back(animation);
  model.buffers[0].uri.clear();
  std::ostringstream stream;
  tinygltf::TinyGLTF writer;
  AMT_CHECK(writer.WriteGltfSceneToStream(&model, stream, false, true), path,
            ": write: expected tinygltf to serialise the model, found an error");
  write_file_atomically(path, stream.str());
}

}  // namespace amt
