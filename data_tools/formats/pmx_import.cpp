// PMX 2.0 / 2.1 reader. Hand-written: no Debian package reads PMX (MMD's model format). Layout from the PMX 2.0
// and 2.1 specifications (PmxEditor's "PMX仕様.txt"): a header, then vertices, faces, textures, materials, bones,
// morphs, display frames, rigid bodies, joints and (2.1 only) soft bodies, all little-endian.
//
// The file is untrusted: every read checks the bytes left, every count is checked against the bytes left before
// anything is allocated, every index against its table, every kept number for finiteness. Errors name the byte
// offset of the offending field and the field's path ("bones[3].parent").
//
// The PMX 2.1 additions (QDEF vertices, flip and impulse morphs, joint types 1 to 5) are accepted in 2.0 files too,
// as other readers do; soft bodies are read only from 2.1 files, and bytes after the last section are ignored.
#include "data_tools/formats/pmx_import.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/pmx_field.h"
#include "data_tools/geometry/mesh.h"

namespace amt {
namespace {

// Field names for messages (data_tools/formats/pmx_field.h).
using Field = PmxField;

// === Text

void append_utf8(uint32_t code_point, std::string& out) {
  if (code_point < 0x80) {
    out += static_cast<char>(code_point);
  } else if (code_point < 0x800) {
    out += static_cast<char>(0xC0 | (code_point >> 6));
    out += static_cast<char>(0x80 | (code_point & 0x3F));
  } else if (code_point < 0x10000) {
    out += static_cast<char>(0xE0 | (code_point >> 12));
    out += static_cast<char>(0x80 | ((code_point >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (code_point & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (code_point >> 18));
    out += static_cast<char>(0x80 | ((code_point >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((code_point >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (code_point & 0x3F));
  }
}

constexpr uint32_t kReplacementCharacter = 0xFFFD;

// See pmx_import.h's sanitize_utf8.
std::string sanitized_utf8(const uint8_t* bytes, size_t size) {
  std::string out;
  out.reserve(size);
  size_t i = 0;
  while (i < size) {
    const uint8_t b = bytes[i];
    size_t length = 0;
    uint32_t code_point = 0, minimum = 0;
    if (b < 0x80) {
      length = 1, code_point = b;
    } else if ((b & 0xE0) == 0xC0) {
      length = 2, code_point = b & 0x1F, minimum = 0x80;
    } else if ((b & 0xF0) == 0xE0) {
      length = 3, code_point = b & 0x0F, minimum = 0x800;
    } else if ((b & 0xF8) == 0xF0) {
      length = 4, code_point = b & 0x07, minimum = 0x10000;
    }
    bool valid = length > 0 && i + length <= size;
    for (size_t k = 1; valid && k < length; ++k) {
      valid = (bytes[i + k] & 0xC0) == 0x80;
      code_point = (code_point << 6) | (bytes[i + k] & 0x3F);
    }
    valid = valid && code_point >= minimum && code_point <= 0x10FFFF && !(code_point >= 0xD800 && code_point <= 0xDFFF);
    if (valid) {
      out.append(reinterpret_cast<const char*>(bytes + i), length);
      i += length;
    } else {
      append_utf8(kReplacementCharacter, out);
      ++i;
    }
  }
  return out;
}

// === Bounds-checked little-endian reader

class Reader {
 public:
  Reader(const uint8_t* data, size_t size, const std::string& source) : data_(data), size_(size), source_(source) {}

  size_t offset() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  void set_encoding(PmxTextEncoding encoding) { encoding_ = encoding; }

  template <typename... Parts>
  [[noreturn]] void fail_at(size_t offset, const Field& field, const Parts&... parts) const {
    fail(source_, ": offset ", offset, ": ", field.str(), ": ", parts...);
  }

  void need(size_t bytes, const Field& field) const {
    if (bytes > remaining()) {
      fail_at(pos_, field, "expected ", bytes, " more bytes, found ", remaining(), " before the end of the file");
    }
  }

  void skip(size_t bytes, const Field& field) {
    need(bytes, field);
    pos_ += bytes;
  }

  uint8_t u8(const Field& field) {
    need(1, field);
    return data_[pos_++];
  }

  uint16_t u16(const Field& field) {
    need(2, field);
    const uint16_t v = static_cast<uint16_t>(data_[pos_] | (data_[pos_ + 1] << 8));
    pos_ += 2;
    return v;
  }

  uint32_t u32(const Field& field) {
    need(4, field);
    const uint32_t v = static_cast<uint32_t>(data_[pos_]) | (static_cast<uint32_t>(data_[pos_ + 1]) << 8) |
                       (static_cast<uint32_t>(data_[pos_ + 2]) << 16) | (static_cast<uint32_t>(data_[pos_ + 3]) << 24);
    pos_ += 4;
    return v;
  }

  int32_t i32(const Field& field) { return static_cast<int32_t>(u32(field)); }

  float f32(const Field& field) {
    const uint32_t bits = u32(field);
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

  float finite_f32(const Field& field) {
    const size_t at = pos_;
    const float v = f32(field);
    if (!std::isfinite(v)) fail_at(at, field, "expected a finite number, found ", v);
    return v;
  }

  template <int N>
  Eigen::Matrix<float, N, 1> finite_vec(const Field& field) {
    const size_t at = pos_;
    need(4 * N, field);
    Eigen::Matrix<float, N, 1> v;
    for (int k = 0; k < N; ++k) v[k] = f32(field);
    if (!v.allFinite()) {
      std::string values;
      for (int k = 0; k < N; ++k) values += (k ? " " : "") + detail::concat(v[k]);
      fail_at(at, field, "expected finite values, found ", values);
    }
    return v;
  }

  Eigen::Vector3f vec3(const Field& field) { return finite_vec<3>(field); }

  // A text: int32 byte length, then that many bytes in the file's encoding. Returns UTF-8.
  std::string text(const Field& field) {
    const size_t at = pos_;
    const int32_t length = i32(field);
    if (length < 0) fail_at(at, field, "expected a text byte length >= 0, found ", length);
    if (static_cast<size_t>(length) > remaining()) {
      fail_at(at, field, "expected a text byte length of at most ", remaining(), " (the rest of the file), found ",
              length);
    }
    const uint8_t* bytes = data_ + pos_;
    pos_ += static_cast<size_t>(length);
    if (encoding_ == PmxTextEncoding::kUtf16Le) {
      if (length % 2 != 0) fail_at(at, field, "expected an even byte length for UTF-16LE text, found ", length);
      return utf16le_to_utf8(bytes, static_cast<size_t>(length));
    }
    return sanitized_utf8(bytes, static_cast<size_t>(length));
  }

  // An int32 element count, checked so that `count` elements of at least `min_element_bytes` bytes each fit in the
  // bytes left: a count read from a damaged file never reaches an allocation.
  int32_t count(const Field& field, size_t min_element_bytes) {
    const size_t at = pos_;
    const int32_t n = i32(field);
    if (n < 0) fail_at(at, field, "expected a count >= 0, found ", n);
    const size_t fit = remaining() / min_element_bytes;
    if (static_cast<size_t>(n) > fit) {
      fail_at(at, field, "expected a count of at most ", fit, " (elements of at least ", min_element_bytes,
              " bytes in the ", remaining(), " bytes left), found ", n);
    }
    return n;
  }

  // A signed index of `size` bytes (1, 2 or 4), not range-checked.
  int32_t signed_index(const Field& field, int size) {
    if (size == 1) return static_cast<int8_t>(u8(field));
    if (size == 2) return static_cast<int16_t>(u16(field));
    return i32(field);
  }

  // A signed index into a table of `table_size` entries; -1 (none) is accepted when `allow_none`.
  int32_t index(const Field& field, int size, int64_t table_size, bool allow_none) {
    const size_t at = pos_;
    const int32_t v = signed_index(field, size);
    check_index(at, field, v, table_size, allow_none);
    return v;
  }

  // A vertex index: unsigned for sizes 1 and 2, signed for 4; must be below `vertex_count`.
  int32_t vertex_index(const Field& field, int size, int64_t vertex_count) {
    const size_t at = pos_;
    int64_t v;
    if (size == 1) {
      v = u8(field);
    } else if (size == 2) {
      v = u16(field);
    } else {
      v = i32(field);
    }
    check_index(at, field, v, vertex_count, false);
    return static_cast<int32_t>(v);
  }

  void check_index(size_t at, const Field& field, int64_t v, int64_t table_size, bool allow_none) const {
    if (allow_none && v == -1) return;
    if (v >= 0 && v < table_size) return;
    if (allow_none) fail_at(at, field, "expected -1 or an index below ", table_size, ", found ", v);
    fail_at(at, field, "expected an index below ", table_size, ", found ", v);
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string source_;
  PmxTextEncoding encoding_ = PmxTextEncoding::kUtf16Le;
};

// === Sections

bool is_version(float v, float expected) {
  return std::fabs(v - expected) < 1e-4f;
}

// Bytes of the bone indices and weights that follow a vertex's deform type byte.
size_t deform_bytes(PmxDeform deform, int bone_index_size) {
  const size_t b = static_cast<size_t>(bone_index_size);
  switch (deform) {
    case PmxDeform::kBdef1:
      return b;
    case PmxDeform::kBdef2:
      return 2 * b + 4;
    case PmxDeform::kSdef:
      return 2 * b + 4 + 36;
    case PmxDeform::kBdef4:
    case PmxDeform::kQdef:
      return 4 * b + 16;
  }
  return 0;
}

int deform_bone_count(PmxDeform deform) {
  switch (deform) {
    case PmxDeform::kBdef1:
      return 1;
    case PmxDeform::kBdef2:
    case PmxDeform::kSdef:
      return 2;
    case PmxDeform::kBdef4:
    case PmxDeform::kQdef:
      return 4;
  }
  return 0;
}

class PmxParser {
 public:
  PmxParser(const uint8_t* data, size_t size, const std::string& source) : in_(data, size, source) {
    model_.source = source;
  }

  PmxModel parse() {
    read_header();
    read_vertices();
    read_faces();
    // Finite but absurd positions (a flipped exponent byte) stop here, in the file's own units.
    check_plausible_extent(TriMesh{model_.vertices.positions, model_.faces}, model_.source);
    if (model_.vertices.positions.rows() > 0) reach_ = model_.vertices.positions.cwiseAbs().maxCoeff();
    read_textures();
    read_materials();
    read_bones();
    check_vertex_bones();
    check_bone_cycles();
    read_morphs();
    read_display_frames();
    read_rigid_bodies();
    read_joints();
    // PMX 2.1 appends soft bodies; a 2.1 file that ends after the joints has none. Bytes after the last section
    // are ignored, as MMD does.
    if (is_version(model_.header.version, 2.1f) && in_.remaining() > 0) read_soft_bodies();
    return std::move(model_);
  }

 private:
  const PmxHeader& h() const { return model_.header; }

  void read_header() {
    PmxHeader& header = model_.header;
    in_.need(4, "header.magic");
    const size_t magic_at = in_.offset();
    uint8_t magic[4];
    for (uint8_t& b : magic) b = in_.u8("header.magic");
    if (std::memcmp(magic, "PMX ", 4) != 0) {
      char found[32];
      std::snprintf(found, sizeof found, "%02x %02x %02x %02x", magic[0], magic[1], magic[2], magic[3]);
      in_.fail_at(magic_at, "header.magic", "expected the bytes 50 4d 58 20 (\"PMX \"), found ", found);
    }
    const size_t version_at = in_.offset();
    header.version = in_.f32("header.version");
    if (!is_version(header.version, 2.0f) && !is_version(header.version, 2.1f)) {
      in_.fail_at(version_at, "header.version", "expected 2.0 or 2.1, found ", header.version);
    }
    const bool v20 = is_version(header.version, 2.0f);
    header.version = v20 ? 2.0f : 2.1f;
    const size_t globals_at = in_.offset();
    const int globals = in_.u8("header.globals_count");
    if (v20 ? globals != 8 : globals < 8) {
      in_.fail_at(globals_at, "header.globals_count", v20 ? "expected 8 for PMX 2.0" : "expected 8 or more", ", found ",
                  globals);
    }
    const size_t encoding_at = in_.offset();
    const int encoding = in_.u8("header.encoding");
    if (encoding > 1)
      in_.fail_at(encoding_at, "header.encoding", "expected 0 (UTF-16LE) or 1 (UTF-8), found ", encoding);
    header.encoding = static_cast<PmxTextEncoding>(encoding);
    in_.set_encoding(header.encoding);
    const size_t uv_at = in_.offset();
    header.additional_uv_count = in_.u8("header.additional_uv_count");
    if (header.additional_uv_count > 4) {
      in_.fail_at(uv_at, "header.additional_uv_count", "expected 0 to 4, found ", header.additional_uv_count);
    }
    header.vertex_index_size = read_index_size("header.vertex_index_size");
    header.texture_index_size = read_index_size("header.texture_index_size");
    header.material_index_size = read_index_size("header.material_index_size");
    header.bone_index_size = read_index_size("header.bone_index_size");
    header.morph_index_size = read_index_size("header.morph_index_size");
    header.rigid_body_index_size = read_index_size("header.rigid_body_index_size");
    in_.skip(static_cast<size_t>(globals - 8), "header.globals");  // later versions' globals
    header.name = in_.text("header.name");
    header.name_english = in_.text("header.name_english");
    header.comment = in_.text("header.comment");
    header.comment_english = in_.text("header.comment_english");
  }

  int read_index_size(const char* field) {
    const size_t at = in_.offset();
    const int size = in_.u8(field);
    if (size != 1 && size != 2 && size != 4) in_.fail_at(at, field, "expected 1, 2 or 4, found ", size);
    return size;
  }

  void read_vertices() {
    const int uv_count = h().additional_uv_count;
    const int bone_size = h().bone_index_size;
    const size_t min_bytes = 32 + 16 * static_cast<size_t>(uv_count) + 1 + static_cast<size_t>(bone_size) + 4;
    const int32_t n = in_.count("vertices", min_bytes);
    vertices_at_ = in_.offset();
    PmxVertices& v = model_.vertices;
    v.resize(n, uv_count);
    for (int32_t i = 0; i < n; ++i) {
      v.positions.row(i) = in_.vec3({"vertices", i, "position"}).transpose();
      v.normals.row(i) = in_.vec3({"vertices", i, "normal"}).transpose();
      v.uvs.row(i) = in_.finite_vec<2>({"vertices", i, "uv"}).transpose();
      for (int k = 0; k < uv_count; ++k) {
        v.additional_uvs[static_cast<size_t>(k)].row(i) =
            in_.finite_vec<4>({"vertices", i, "additional_uv", k}).transpose();
      }
      const size_t deform_at = in_.offset();
      const int deform = in_.u8({"vertices", i, "deform"});
      if (deform > 4) {
        in_.fail_at(deform_at, {"vertices", i, "deform"},
                    "expected 0 (BDEF1), 1 (BDEF2), 2 (BDEF4), 3 (SDEF) or 4 (QDEF), found ", deform);
      }
      const auto type = static_cast<PmxDeform>(deform);
      v.deform[static_cast<size_t>(i)] = type;
      const int bones = deform_bone_count(type);
      for (int k = 0; k < bones; ++k) v.bone_indices(i, k) = in_.signed_index({"vertices", i, "bones", k}, bone_size);
      switch (type) {
        case PmxDeform::kBdef1:
          v.bone_weights(i, 0) = 1;
          break;
        case PmxDeform::kBdef2:
        case PmxDeform::kSdef: {
          const float w = in_.finite_f32({"vertices", i, "weights", 0});
          v.bone_weights(i, 0) = w;
          v.bone_weights(i, 1) = 1 - w;
          if (type == PmxDeform::kSdef) {
            v.sdef_c.row(i) = in_.vec3({"vertices", i, "sdef_c"}).transpose();
            v.sdef_r0.row(i) = in_.vec3({"vertices", i, "sdef_r0"}).transpose();
            v.sdef_r1.row(i) = in_.vec3({"vertices", i, "sdef_r1"}).transpose();
          }
          break;
        }
        case PmxDeform::kBdef4:
        case PmxDeform::kQdef:
          for (int k = 0; k < 4; ++k) v.bone_weights(i, k) = in_.finite_f32({"vertices", i, "weights", k});
          break;
      }
      v.edge_scale[i] = in_.finite_f32({"vertices", i, "edge_scale"});
    }
  }

  void read_faces() {
    const int size = h().vertex_index_size;
    const size_t at = in_.offset();
    const int32_t n = in_.count("faces", static_cast<size_t>(size));
    if (n % 3 != 0) in_.fail_at(at, "faces", "expected a multiple of 3 vertex indices, found ", n);
    const int64_t vertex_count = model_.vertices.size();
    model_.faces.resize(n / 3, 3);
    for (int32_t f = 0; f < n / 3; ++f) {
      for (int k = 0; k < 3; ++k) model_.faces(f, k) = in_.vertex_index({"faces", f, nullptr, k}, size, vertex_count);
    }
  }

  void read_textures() {
    model_.texture_count = in_.count("textures", 4);
    model_.textures.reserve(static_cast<size_t>(model_.texture_count));
    for (int32_t i = 0; i < model_.texture_count; ++i) model_.textures.push_back(in_.text({"textures", i}));
  }

  void read_materials() {
    const int ti = h().texture_index_size;
    const int64_t textures = model_.texture_count;
    model_.material_count = in_.count("materials", 84 + 2 * static_cast<size_t>(ti));
    model_.materials.resize(static_cast<size_t>(model_.material_count));
    int64_t faces_left = model_.faces.rows();  // faces not yet drawn by an earlier material
    for (int32_t i = 0; i < model_.material_count; ++i) {
      PmxMaterial& m = model_.materials[static_cast<size_t>(i)];
      m.name = in_.text({"materials", i, "name"});
      m.name_english = in_.text({"materials", i, "name_english"});
      m.diffuse = in_.finite_vec<4>({"materials", i, "diffuse"});
      m.specular = in_.vec3({"materials", i, "specular"});
      m.specular_strength = in_.finite_f32({"materials", i, "specular_strength"});
      m.ambient = in_.vec3({"materials", i, "ambient"});
      m.flags = in_.u8({"materials", i, "flags"});
      m.edge_colour = in_.finite_vec<4>({"materials", i, "edge_colour"});
      m.edge_size = in_.finite_f32({"materials", i, "edge_size"});
      m.texture = in_.index({"materials", i, "texture"}, ti, textures, true);
      m.sphere_texture = in_.index({"materials", i, "sphere_texture"}, ti, textures, true);
      size_t at = in_.offset();
      const int sphere_mode = in_.u8({"materials", i, "sphere_mode"});
      if (sphere_mode > 3) {
        in_.fail_at(at, {"materials", i, "sphere_mode"},
                    "expected 0 (none), 1 (multiply), 2 (add) or 3 (sub-texture), found ", sphere_mode);
      }
      m.sphere_mode = static_cast<PmxSphereMode>(sphere_mode);
      at = in_.offset();
      const int shared_toon = in_.u8({"materials", i, "toon_flag"});
      if (shared_toon > 1) {
        in_.fail_at(at, {"materials", i, "toon_flag"}, "expected 0 (texture) or 1 (shared toon), found ", shared_toon);
      }
      m.shared_toon = shared_toon == 1;
      m.toon =
          m.shared_toon ? in_.u8({"materials", i, "toon"}) : in_.index({"materials", i, "toon"}, ti, textures, true);
      m.memo = in_.text({"materials", i, "memo"});
      at = in_.offset();
      const int32_t indices = in_.i32({"materials", i, "face_index_count"});
      if (indices < 0 || indices % 3 != 0 || indices / 3 > faces_left) {
        in_.fail_at(at, {"materials", i, "face_index_count"}, "expected a multiple of 3 from 0 to ", 3 * faces_left,
                    " (the face indices no earlier material draws), found ", indices);
      }
      m.face_count = indices / 3;
      faces_left -= m.face_count;
    }
  }

  void read_bones() {
    const int bi = h().bone_index_size;
    const int32_t n = in_.count("bones", 26 + 2 * static_cast<size_t>(bi));
    model_.bones.resize(static_cast<size_t>(n));
    parent_at_.resize(static_cast<size_t>(n));
    for (int32_t i = 0; i < n; ++i) {
      PmxBone& b = model_.bones[static_cast<size_t>(i)];
      b.name = in_.text({"bones", i, "name"});
      b.name_english = in_.text({"bones", i, "name_english"});
      b.position = plausible({"bones", i, "position"}, "position");
      parent_at_[static_cast<size_t>(i)] = in_.offset();
      b.parent = in_.index({"bones", i, "parent"}, bi, n, true);
      if (b.parent == i) {
        in_.fail_at(parent_at_[static_cast<size_t>(i)], {"bones", i, "parent"},
                    "expected another bone or -1, found the bone itself (", i, ")");
      }
      b.layer = in_.i32({"bones", i, "layer"});
      b.flags = in_.u16({"bones", i, "flags"});
      decode_flags(b);
      if (b.tail_is_bone) {
        b.tail_bone = in_.index({"bones", i, "tail_bone"}, bi, n, true);
      } else {
        b.tail_offset = in_.vec3({"bones", i, "tail_offset"});
      }
      if (b.inherit_rotation || b.inherit_translation) {
        b.inherit_parent = in_.index({"bones", i, "inherit_parent"}, bi, n, true);
        b.inherit_weight = in_.finite_f32({"bones", i, "inherit_weight"});
      }
      if (b.has_fixed_axis) b.fixed_axis = in_.vec3({"bones", i, "fixed_axis"});
      if (b.has_local_axes) {
        b.local_axis_x = in_.vec3({"bones", i, "local_axis_x"});
        b.local_axis_z = in_.vec3({"bones", i, "local_axis_z"});
      }
      if (b.has_external_parent) b.external_parent_key = in_.i32({"bones", i, "external_parent_key"});
      if (b.is_ik) read_ik(i, n, b.ik);
    }
  }

  static void decode_flags(PmxBone& b) {
    const uint16_t f = b.flags;
    b.tail_is_bone = f & kPmxBoneTailIsBone;
    b.rotatable = f & kPmxBoneRotatable;
    b.translatable = f & kPmxBoneTranslatable;
    b.visible = f & kPmxBoneVisible;
    b.enabled = f & kPmxBoneEnabled;
    b.is_ik = f & kPmxBoneIk;
    b.inherit_local = f & kPmxBoneInheritLocal;
    b.inherit_rotation = f & kPmxBoneInheritRotation;
    b.inherit_translation = f & kPmxBoneInheritTranslation;
    b.has_fixed_axis = f & kPmxBoneFixedAxis;
    b.has_local_axes = f & kPmxBoneLocalAxes;
    b.physics_after_deform = f & kPmxBonePhysicsAfterDeform;
    b.has_external_parent = f & kPmxBoneExternalParent;
  }

  void read_ik(int32_t i, int32_t bone_count, PmxIk& ik) {
    const int bi = h().bone_index_size;
    ik.target = in_.index({"bones", i, "ik.target"}, bi, bone_count, false);
    const size_t loop_at = in_.offset();
    ik.loop_count = in_.i32({"bones", i, "ik.loop_count"});
    if (ik.loop_count < 0) in_.fail_at(loop_at, {"bones", i, "ik.loop_count"}, "expected >= 0, found ", ik.loop_count);
    ik.limit_angle = in_.finite_f32({"bones", i, "ik.limit_angle"});
    const int32_t links = in_.count({"bones", i, "ik.links"}, static_cast<size_t>(bi) + 1);
    ik.links.resize(static_cast<size_t>(links));
    for (int32_t k = 0; k < links; ++k) {
      PmxIkLink& link = ik.links[static_cast<size_t>(k)];
      link.bone = in_.index({"bones", i, "ik.links", k, "bone"}, bi, bone_count, false);
      link.has_limits = in_.u8({"bones", i, "ik.links", k, "has_limits"}) != 0;
      if (link.has_limits) {
        link.limit_min = in_.vec3({"bones", i, "ik.links", k, "limit_min"});
        link.limit_max = in_.vec3({"bones", i, "ik.links", k, "limit_max"});
      }
    }
  }

  // Vertex bone indices are read before the bone table; check them against it now. The offset in the message is
  // recomputed from the vertex layout (only on error).
  void check_vertex_bones() {
    const PmxVertices& v = model_.vertices;
    const int64_t bone_count = static_cast<int64_t>(model_.bones.size());
    for (int i = 0; i < v.size(); ++i) {
      const int bones = deform_bone_count(v.deform[static_cast<size_t>(i)]);
      for (int k = 0; k < bones; ++k) {
        const int32_t b = v.bone_indices(i, k);
        if (b == -1 || (b >= 0 && b < bone_count)) continue;
        in_.check_index(vertex_bone_offset(i, k), {"vertices", i, "bones", k}, b, bone_count, true);
      }
    }
  }

  size_t vertex_bone_offset(int vertex, int slot) const {
    const size_t head = 32 + 16 * static_cast<size_t>(h().additional_uv_count);
    size_t at = vertices_at_;
    for (int i = 0; i < vertex; ++i) {
      at += head + 1 + deform_bytes(model_.vertices.deform[static_cast<size_t>(i)], h().bone_index_size) + 4;
    }
    return at + head + 1 + static_cast<size_t>(slot) * static_cast<size_t>(h().bone_index_size);
  }

  // Parents may follow children in a PMX file, so a cycle is possible; walk every chain once (O(#bones)).
  void check_bone_cycles() {
    const size_t n = model_.bones.size();
    std::vector<uint8_t> state(n, 0);  // 0 unvisited, 1 on the current chain, 2 known to reach a root
    std::vector<int32_t> chain;
    for (size_t start = 0; start < n; ++start) {
      chain.clear();
      int32_t j = static_cast<int32_t>(start);
      while (j >= 0 && state[static_cast<size_t>(j)] == 0) {
        state[static_cast<size_t>(j)] = 1;
        chain.push_back(j);
        j = model_.bones[static_cast<size_t>(j)].parent;
      }
      if (j >= 0 && state[static_cast<size_t>(j)] == 1) {
        in_.fail_at(parent_at_[static_cast<size_t>(j)], {"bones", j, "parent"},
                    "expected a hierarchy without cycles, found a parent cycle through bone ", j, " (parent ",
                    model_.bones[static_cast<size_t>(j)].parent, ")");
      }
      for (int32_t c : chain) state[static_cast<size_t>(c)] = 2;
    }
  }

  void read_morphs() {
    const size_t vi = static_cast<size_t>(h().vertex_index_size);
    const size_t bi = static_cast<size_t>(h().bone_index_size);
    const size_t mi = static_cast<size_t>(h().morph_index_size);
    const size_t mati = static_cast<size_t>(h().material_index_size);
    const size_t ri = static_cast<size_t>(h().rigid_body_index_size);
    // Bytes per offset of each morph type: group, vertex, bone, uv, 4 additional uv, material, flip (2.1),
    // impulse (2.1).
    const size_t offset_bytes[11] = {mi + 4,  vi + 12, bi + 28,           vi + 16, vi + 16,    vi + 16,
                                     vi + 16, vi + 16, mati + 1 + 28 * 4, mi + 4,  ri + 1 + 24};
    model_.morph_count = in_.count("morphs", 14);
    for (int32_t i = 0; i < model_.morph_count; ++i) {
      in_.text({"morphs", i, "name"});
      in_.text({"morphs", i, "name_english"});
      in_.u8({"morphs", i, "panel"});
      const size_t type_at = in_.offset();
      const int type = in_.u8({"morphs", i, "type"});
      if (type > 10) in_.fail_at(type_at, {"morphs", i, "type"}, "expected a morph type 0 to 10, found ", type);
      const size_t bytes = offset_bytes[type];
      const int32_t offsets = in_.count({"morphs", i, "offsets"}, bytes);
      in_.skip(static_cast<size_t>(offsets) * bytes, {"morphs", i, "offsets"});
    }
  }

  void read_display_frames() {
    const size_t bi = static_cast<size_t>(h().bone_index_size);
    const size_t mi = static_cast<size_t>(h().morph_index_size);
    model_.display_frame_count = in_.count("display_frames", 13);
    for (int32_t i = 0; i < model_.display_frame_count; ++i) {
      in_.text({"display_frames", i, "name"});
      in_.text({"display_frames", i, "name_english"});
      in_.u8({"display_frames", i, "special"});
      const int32_t elements = in_.count({"display_frames", i, "elements"}, 1 + std::min(bi, mi));
      for (int32_t k = 0; k < elements; ++k) {
        const size_t type_at = in_.offset();
        const int type = in_.u8({"display_frames", i, "elements", k, "type"});
        if (type > 1) {
          in_.fail_at(type_at, {"display_frames", i, "elements", k, "type"}, "expected 0 (bone) or 1 (morph), found ",
                      type);
        }
        in_.skip(type == 0 ? bi : mi, {"display_frames", i, "elements", k, "index"});
      }
    }
  }

  void read_rigid_bodies() {
    const int bi = h().bone_index_size;
    const int64_t bone_count = static_cast<int64_t>(model_.bones.size());
    const int32_t n = in_.count("rigid_bodies", 69 + static_cast<size_t>(bi));
    model_.rigid_bodies.resize(static_cast<size_t>(n));
    for (int32_t i = 0; i < n; ++i) {
      PmxRigidBody& r = model_.rigid_bodies[static_cast<size_t>(i)];
      r.name = in_.text({"rigid_bodies", i, "name"});
      r.name_english = in_.text({"rigid_bodies", i, "name_english"});
      r.bone = in_.index({"rigid_bodies", i, "bone"}, bi, bone_count, true);
      size_t at = in_.offset();
      r.group = in_.u8({"rigid_bodies", i, "group"});
      if (r.group > 15) in_.fail_at(at, {"rigid_bodies", i, "group"}, "expected 0 to 15, found ", int(r.group));
      r.collision_mask = in_.u16({"rigid_bodies", i, "collision_mask"});
      at = in_.offset();
      const int shape = in_.u8({"rigid_bodies", i, "shape"});
      if (shape > 2) {
        in_.fail_at(at, {"rigid_bodies", i, "shape"}, "expected 0 (sphere), 1 (box) or 2 (capsule), found ", shape);
      }
      r.shape = static_cast<PmxShape>(shape);
      at = in_.offset();
      r.size = plausible({"rigid_bodies", i, "size"}, "size");
      if ((r.size.array() < 0).any()) {
        in_.fail_at(at, {"rigid_bodies", i, "size"}, "expected sizes >= 0, found ", r.size.x(), " ", r.size.y(), " ",
                    r.size.z());
      }
      r.position = plausible({"rigid_bodies", i, "position"}, "position");
      r.rotation = in_.vec3({"rigid_bodies", i, "rotation"});
      at = in_.offset();
      r.mass = in_.finite_f32({"rigid_bodies", i, "mass"});
      if (r.mass < 0 || r.mass > kMaxMass) {
        in_.fail_at(at, {"rigid_bodies", i, "mass"}, "expected a mass in [0, ", kMaxMass, "], found ", r.mass);
      }
      r.linear_damping = in_.finite_f32({"rigid_bodies", i, "linear_damping"});
      r.angular_damping = in_.finite_f32({"rigid_bodies", i, "angular_damping"});
      r.restitution = in_.finite_f32({"rigid_bodies", i, "restitution"});
      r.friction = in_.finite_f32({"rigid_bodies", i, "friction"});
      at = in_.offset();
      const int mode = in_.u8({"rigid_bodies", i, "mode"});
      if (mode > 2) {
        in_.fail_at(at, {"rigid_bodies", i, "mode"},
                    "expected 0 (follow bone), 1 (dynamic) or 2 (dynamic with bone position), found ", mode);
      }
      r.mode = static_cast<PmxPhysicsMode>(mode);
    }
  }

  void read_joints() {
    const int ri = h().rigid_body_index_size;
    const int64_t body_count = static_cast<int64_t>(model_.rigid_bodies.size());
    const int32_t n = in_.count("joints", 105 + 2 * static_cast<size_t>(ri));
    model_.joints.resize(static_cast<size_t>(n));
    for (int32_t i = 0; i < n; ++i) {
      PmxJoint& j = model_.joints[static_cast<size_t>(i)];
      j.name = in_.text({"joints", i, "name"});
      j.name_english = in_.text({"joints", i, "name_english"});
      const size_t at = in_.offset();
      const int type = in_.u8({"joints", i, "type"});
      if (type > 5) {
        in_.fail_at(at, {"joints", i, "type"},
                    "expected 0 (spring 6DOF), 1 (6DOF), 2 (point), 3 (cone twist), 4 (slider) or 5 (hinge), found ",
                    type);
      }
      j.type = static_cast<PmxJointType>(type);
      j.rigid_body_a = in_.index({"joints", i, "rigid_body_a"}, ri, body_count, true);
      j.rigid_body_b = in_.index({"joints", i, "rigid_body_b"}, ri, body_count, true);
      j.position = plausible({"joints", i, "position"}, "position");
      j.rotation = in_.vec3({"joints", i, "rotation"});
      j.linear_min = in_.vec3({"joints", i, "linear_min"});
      j.linear_max = in_.vec3({"joints", i, "linear_max"});
      j.angular_min = in_.vec3({"joints", i, "angular_min"});
      j.angular_max = in_.vec3({"joints", i, "angular_max"});
      j.spring_linear = in_.vec3({"joints", i, "spring_linear"});
      j.spring_angular = in_.vec3({"joints", i, "spring_angular"});
    }
  }

  void read_soft_bodies() {
    const size_t vi = static_cast<size_t>(h().vertex_index_size);
    const size_t mati = static_cast<size_t>(h().material_index_size);
    const size_t ri = static_cast<size_t>(h().rigid_body_index_size);
    // After the names: shape, material index, group, mask, flags, B-link distance, cluster count, total mass,
    // margin, aerodynamics model, 12 config floats, 6 cluster floats, 4 iteration ints, 3 material values.
    const size_t fixed_bytes = 1 + mati + 1 + 2 + 1 + 5 * 4 + (12 + 6 + 4 + 3) * 4;
    model_.soft_body_count = in_.count("soft_bodies", 8 + fixed_bytes + 8);
    for (int32_t i = 0; i < model_.soft_body_count; ++i) {
      in_.text({"soft_bodies", i, "name"});
      in_.text({"soft_bodies", i, "name_english"});
      in_.skip(fixed_bytes, {"soft_bodies", i, "parameters"});
      const int32_t anchors = in_.count({"soft_bodies", i, "anchors"}, ri + vi + 1);
      in_.skip(static_cast<size_t>(anchors) * (ri + vi + 1), {"soft_bodies", i, "anchors"});
      const int32_t pins = in_.count({"soft_bodies", i, "pins"}, vi);
      in_.skip(static_cast<size_t>(pins) * vi, {"soft_bodies", i, "pins"});
    }
  }

  // Physics and bones beyond this many times the model's reach (its largest vertex coordinate) are a damaged
  // file (a flipped exponent byte), not a model: the simulation would write them into the output. Masses beyond
  // kMaxMass likewise (MMD models use 0.1 to 10).
  static constexpr float kMaxReaches = 10.0f;
  static constexpr float kMaxMass = 1e6f;

  // A vec3 (`what`: "position" or "size") within kMaxReaches reaches of the origin; any finite value on a model
  // without vertices.
  Eigen::Vector3f plausible(const Field& field, const char* what) {
    const size_t at = in_.offset();
    const Eigen::Vector3f v = in_.vec3(field);
    const float bound = kMaxReaches * reach_;
    if (reach_ > 0 && v.cwiseAbs().maxCoeff() > bound) {
      in_.fail_at(at, field, "expected a ", what, " within ", bound, " of the origin (", kMaxReaches,
                  " times the model's largest vertex coordinate), found ", v.x(), " ", v.y(), " ", v.z());
    }
    return v;
  }

  Reader in_;
  PmxModel model_;
  float reach_ = 0;  // the largest vertex coordinate, file units
  size_t vertices_at_ = 0;         // offset of the first vertex
  std::vector<size_t> parent_at_;  // offset of each bone's parent field
};

}  // namespace

// === Reading

// PMX counts and lengths are int32: larger files are damaged or not PMX, and are not read into memory.
constexpr uintmax_t kMaxFileBytes = uintmax_t(1) << 31;

PmxModel parse_pmx(const uint8_t* data, size_t size, const std::string& source) {
  if (data == nullptr) size = 0;
  return PmxParser(data, size, source).parse();
}

PmxModel read_pmx(const std::string& path) {
  const uint64_t size = check_input_file(path, "a PMX model");
  AMT_CHECK(size < kMaxFileBytes, path, ": expected a PMX file of less than 2 GiB, found ", size, " bytes");
  std::ifstream file(path, std::ios::binary);
  AMT_CHECK(file, path, ": cannot open the file for reading");
  std::vector<uint8_t> bytes;
  char chunk[1 << 16];
  while (file.read(chunk, sizeof chunk) || file.gcount() > 0) {
    bytes.insert(bytes.end(), chunk, chunk + file.gcount());
  }
  AMT_CHECK(file.eof() && !file.bad(), path, ": read error after ", bytes.size(), " bytes");
  return parse_pmx(bytes.data(), bytes.size(), path);
}

// === Conversion to amt's conventions

Eigen::Vector3f pmx_to_amt_position(const Eigen::Vector3f& p, float scale) {
  return Eigen::Vector3f(scale * p.x(), scale * p.y(), -scale * p.z());
}

Eigen::Vector3f pmx_to_amt_direction(const Eigen::Vector3f& d) {
  return Eigen::Vector3f(d.x(), d.y(), -d.z());
}

Eigen::Vector3f pmx_to_amt_euler(const Eigen::Vector3f& euler) {
  return Eigen::Vector3f(-euler.x(), -euler.y(), euler.z());
}

void pmx_to_amt_angle_range(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, Eigen::Vector3f& out_lo,
                            Eigen::Vector3f& out_hi) {
  const Eigen::Vector3f new_lo(-hi.x(), -hi.y(), lo.z());
  const Eigen::Vector3f new_hi(-lo.x(), -lo.y(), hi.z());
  out_lo = new_lo;
  out_hi = new_hi;
}

void pmx_to_amt_length_range(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float scale, Eigen::Vector3f& out_lo,
                             Eigen::Vector3f& out_hi) {
  const Eigen::Vector3f new_lo(scale * lo.x(), scale * lo.y(), -scale * hi.z());
  const Eigen::Vector3f new_hi(scale * hi.x(), scale * hi.y(), -scale * lo.z());
  out_lo = new_lo;
  out_hi = new_hi;
}

Eigen::Matrix3f pmx_euler_rotation(const Eigen::Vector3f& euler) {
  return (Eigen::AngleAxisf(euler.y(), Eigen::Vector3f::UnitY()) *
          Eigen::AngleAxisf(euler.x(), Eigen::Vector3f::UnitX()) *
          Eigen::AngleAxisf(euler.z(), Eigen::Vector3f::UnitZ()))
      .toRotationMatrix();
}

PmxModel pmx_to_amt_frame(const PmxModel& model, float scale) {
  AMT_CHECK(model.frame == PmxFrame::kMmd, model.source,
            ": pmx_to_amt_frame: expected a model in the file's frame, found one already converted");
  AMT_CHECK(std::isfinite(scale) && scale > 0, model.source, ": pmx_to_amt_frame: expected a finite scale > 0, found ",
            scale);
  PmxModel out = model;
  out.frame = PmxFrame::kAmt;
  out.scale = scale;

  // S = diag(1, 1, -1): negate the Z column of positions and directions.
  PmxVertices& v = out.vertices;
  const auto to_amt = [](MatrixX3f& points, float factor) {
    if (points.rows() == 0) return;  // a column block of an empty matrix offsets a null pointer
    points *= factor;
    points.col(2) *= -1.0f;
  };
  to_amt(v.positions, scale);
  to_amt(v.normals, 1.0f);
  to_amt(v.sdef_c, scale);
  to_amt(v.sdef_r0, scale);
  to_amt(v.sdef_r1, scale);
  if (out.faces.rows() > 0) out.faces.col(1).swap(out.faces.col(2));  // the reflection reverses winding

  for (PmxBone& b : out.bones) {
    b.position = pmx_to_amt_position(b.position, scale);
    b.tail_offset = pmx_to_amt_position(b.tail_offset, scale);
    b.fixed_axis = pmx_to_amt_direction(b.fixed_axis);
    b.local_axis_x = pmx_to_amt_direction(b.local_axis_x);
    b.local_axis_z = pmx_to_amt_direction(b.local_axis_z);
    for (PmxIkLink& link : b.ik.links)
      pmx_to_amt_angle_range(link.limit_min, link.limit_max, link.limit_min, link.limit_max);
  }
  for (PmxRigidBody& r : out.rigid_bodies) {
    r.size *= scale;
    r.position = pmx_to_amt_position(r.position, scale);
    r.rotation = pmx_to_amt_euler(r.rotation);
  }
  for (PmxJoint& j : out.joints) {
    j.position = pmx_to_amt_position(j.position, scale);
    j.rotation = pmx_to_amt_euler(j.rotation);
    pmx_to_amt_length_range(j.linear_min, j.linear_max, scale, j.linear_min, j.linear_max);
    pmx_to_amt_angle_range(j.angular_min, j.angular_max, j.angular_min, j.angular_max);
  }
  return out;
}

// === Mesh and skinning

void PmxVertices::resize(int n, int additional_uv_count) {
  positions.setZero(n, 3);
  normals.setZero(n, 3);
  uvs.setZero(n, 2);
  additional_uvs.assign(static_cast<size_t>(additional_uv_count),
                        Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor>::Zero(n, 4));
  deform.assign(static_cast<size_t>(n), PmxDeform::kBdef1);
  bone_indices.setConstant(n, 4, -1);
  bone_weights.setZero(n, 4);
  sdef_c.setZero(n, 3);
  sdef_r0.setZero(n, 3);
  sdef_r1.setZero(n, 3);
  edge_scale.setOnes(n);
}

TriMesh pmx_mesh(const PmxModel& model) {
  TriMesh mesh;
  mesh.V = model.vertices.positions;
  mesh.F = model.faces;
  return mesh;
}

SparseWeights pmx_skin_weights(const PmxModel& model) {
  const PmxVertices& v = model.vertices;
  const int n = v.size();
  const int bone_count = static_cast<int>(model.bones.size());
  AMT_CHECK(n == 0 || bone_count > 0, model.source, ": bones: expected at least 1 bone to skin ", n,
            " vertices, found none");
  SparseWeights out;
  out.indices.setZero(n, kMaxInfluences);
  out.weights.setZero(n, kMaxInfluences);
  for (int i = 0; i < n; ++i) {
    int used = 0;
    int32_t first_bone = -1;
    for (int k = 0; k < kMaxInfluences; ++k) {
      const int32_t bone = v.bone_indices(i, k);
      if (bone < 0 || bone >= bone_count) continue;
      if (first_bone < 0) first_bone = bone;
      const float w = std::max(v.bone_weights(i, k), 0.0f);
      if (!(w > 0)) continue;
      int slot = 0;
      while (slot < used && out.indices(i, slot) != bone) ++slot;
      if (slot == used) out.indices(i, used++) = bone;
      out.weights(i, slot) += w;
    }
    const float total = out.weights.row(i).sum();
    if (used == 0 || !(total > 0) || !std::isfinite(total)) {
      out.indices.row(i).setZero();
      out.weights.row(i).setZero();
      out.indices(i, 0) = first_bone >= 0 ? first_bone : 0;
      out.weights(i, 0) = 1;
    } else {
      out.weights.row(i) /= total;
    }
  }
  return out;
}

// === Text

std::string utf16le_to_utf8(const uint8_t* bytes, size_t size) {
  std::string out;
  out.reserve(size + size / 2);
  const size_t units = size / 2;
  const auto unit = [bytes](size_t k) { return static_cast<uint32_t>(bytes[2 * k] | (bytes[2 * k + 1] << 8)); };
  for (size_t k = 0; k < units; ++k) {
    const uint32_t u = unit(k);
    if (u >= 0xD800 && u <= 0xDBFF && k + 1 < units && unit(k + 1) >= 0xDC00 && unit(k + 1) <= 0xDFFF) {
      append_utf8(0x10000 + ((u - 0xD800) << 10) + (unit(k + 1) - 0xDC00), out);
      ++k;
    } else if (u >= 0xD800 && u <= 0xDFFF) {
      append_utf8(kReplacementCharacter, out);  // unpaired surrogate
    } else {
      append_utf8(u, out);
    }
  }
  if (size % 2 != 0) append_utf8(kReplacementCharacter, out);
  return out;
}

std::string sanitize_utf8(const std::string& text) {
  return sanitized_utf8(reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

}  // namespace amt
