// PMX 2.0 / 2.1 writer. Layout from the PMX 2.0 and 2.1 specifications (PmxEditor's "PMX仕様.txt"), section by
// section as data_tools/formats/pmx_import.cpp reads it: header, vertices, faces, textures, materials, bones,
// morphs, display frames, rigid bodies, joints and (2.1) soft bodies, all little-endian.
#include "data_tools/formats/pmx_export.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string_view>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"

namespace amt {

// === Encoding

std::vector<uint8_t> utf8_to_utf16le(const std::string& text) {
  const std::string s = sanitize_utf8(text);  // well-formed from here on: every sequence is complete
  std::vector<uint8_t> out;
  out.reserve(2 * s.size());
  const auto put = [&out](uint32_t unit) {
    out.push_back(static_cast<uint8_t>(unit & 0xFF));
    out.push_back(static_cast<uint8_t>(unit >> 8));
  };
  for (size_t i = 0; i < s.size();) {
    const uint8_t lead = static_cast<uint8_t>(s[i]);
    const int length = lead < 0x80 ? 1 : lead < 0xE0 ? 2 : lead < 0xF0 ? 3 : 4;
    uint32_t code_point = length == 1 ? lead : lead & (0x7Fu >> length);
    for (int k = 1; k < length; ++k) code_point = code_point << 6 | (static_cast<uint8_t>(s[i + k]) & 0x3F);
    i += static_cast<size_t>(length);
    if (code_point >= 0x10000) {
      put(0xD800 + ((code_point - 0x10000) >> 10));
      put(0xDC00 + ((code_point - 0x10000) & 0x3FF));
    } else {
      put(code_point);
    }
  }
  return out;
}

void PmxEncoder::u16(uint16_t v) {
  u8(static_cast<uint8_t>(v & 0xFF));
  u8(static_cast<uint8_t>(v >> 8));
}

void PmxEncoder::i32(int32_t v) {
  const uint32_t u = static_cast<uint32_t>(v);
  for (int k = 0; k < 4; ++k) u8(static_cast<uint8_t>((u >> (8 * k)) & 0xFF));
}

void PmxEncoder::f32(float v) {
  uint32_t u;
  std::memcpy(&u, &v, sizeof u);
  i32(static_cast<int32_t>(u));
}

void PmxEncoder::vec3(const Eigen::Vector3f& v) {
  for (int k = 0; k < 3; ++k) f32(v[k]);
}

void PmxEncoder::text(const std::string& utf8) {
  if (header_.encoding == PmxTextEncoding::kUtf16Le) {
    const std::vector<uint8_t> units = utf8_to_utf16le(utf8);
    i32(static_cast<int32_t>(units.size()));
    bytes.insert(bytes.end(), units.begin(), units.end());
  } else {
    i32(static_cast<int32_t>(utf8.size()));
    bytes.insert(bytes.end(), utf8.begin(), utf8.end());
  }
}

void PmxEncoder::index(int32_t v, int size, const PmxField& field) {
  if (size == 4) return i32(v);
  const int32_t limit = size == 1 ? 0x7F : 0x7FFF;
  AMT_CHECK(v >= -limit - 1 && v <= limit, field.str(), ": expected an index from ", -limit - 1, " to ", limit, " (",
            size, "-byte indices), found ", v);
  if (size == 1) return u8(static_cast<uint8_t>(static_cast<int8_t>(v)));
  u16(static_cast<uint16_t>(static_cast<int16_t>(v)));
}

void PmxEncoder::vertex_index(int32_t v, const PmxField& field) {
  const int size = header_.vertex_index_size;
  if (size == 4) return i32(v);
  const int32_t limit = size == 1 ? 0xFF : 0xFFFF;
  AMT_CHECK(v >= 0 && v <= limit, field.str(), ": expected a vertex index from 0 to ", limit, " (", size,
            "-byte vertex indices), found ", v);
  if (size == 1) return u8(static_cast<uint8_t>(v));
  u16(static_cast<uint16_t>(v));
}

// Ry(y) Rx(x) Rz(z) has R(1, 2) = -sin x, (R(0, 2), R(2, 2)) = cos x (sin y, cos y) and (R(1, 0), R(1, 1)) =
// cos x (sin z, cos z); at cos x = 0 and z = 0, (R(0, 0), R(2, 0)) = (cos y, -sin y).
Eigen::Vector3f pmx_euler_angles(const Eigen::Matrix3f& R) {
  const float x = std::asin(std::clamp(-R(1, 2), -1.0f, 1.0f));
  if (std::hypot(R(1, 0), R(1, 1)) < 1e-6f) return Eigen::Vector3f(x, std::atan2(-R(2, 0), R(0, 0)), 0.0f);
  return Eigen::Vector3f(x, std::atan2(R(0, 2), R(2, 2)), std::atan2(R(1, 0), R(1, 1)));
}

namespace {

// === Checks of what the format can hold

bool is_index_size(int size) {
  return size == 1 || size == 2 || size == 4;
}

// The most table entries `size`-byte indices can address: signed ones keep -1 for "none".
int64_t signed_capacity(int size) {
  return size == 1 ? 0x80 : size == 2 ? 0x8000 : int64_t(0x80000000);
}

int64_t vertex_capacity(int size) {
  return size == 1 ? 0x100 : size == 2 ? 0x10000 : int64_t(0x80000000);
}

// The model's materials, or, for a model without any, one material drawing every face (see the top of
// pmx_export.h).
int64_t written_material_count(const PmxModel& m) {
  return std::max<int64_t>(1, static_cast<int64_t>(m.materials.size()));
}

// `s` names the model in messages.
void check_encodable(const PmxModel& m, const std::string& s) {
  const PmxHeader& h = m.header;
  AMT_CHECK(m.frame == PmxFrame::kMmd, s,
            ": frame: expected a model in PMX's own frame and units (PmxFrame::kMmd), found one in amt's frame");
  AMT_CHECK(h.version == 2.0f || h.version == 2.1f, s, ": header.version: expected 2.0 or 2.1, found ", h.version);
  AMT_CHECK(h.encoding == PmxTextEncoding::kUtf16Le || h.encoding == PmxTextEncoding::kUtf8, s,
            ": header.encoding: expected 0 (UTF-16LE) or 1 (UTF-8), found ", int(h.encoding));
  AMT_CHECK(h.additional_uv_count >= 0 && h.additional_uv_count <= 4, s,
            ": header.additional_uv_count: expected 0 to 4, found ", h.additional_uv_count);
  const struct {
    const char* field;
    int size;
    int64_t entries;
    bool is_vertex;
  } tables[] = {
      {"header.vertex_index_size", h.vertex_index_size, m.vertices.size(), true},
      {"header.texture_index_size", h.texture_index_size, static_cast<int64_t>(m.textures.size()), false},
      {"header.material_index_size", h.material_index_size, written_material_count(m), false},
      {"header.bone_index_size", h.bone_index_size, static_cast<int64_t>(m.bones.size()), false},
      {"header.morph_index_size", h.morph_index_size, 0, false},
      {"header.rigid_body_index_size", h.rigid_body_index_size, static_cast<int64_t>(m.rigid_bodies.size()), false},
  };
  for (const auto& t : tables) {
    AMT_CHECK(is_index_size(t.size), s, ": ", t.field, ": expected 1, 2 or 4, found ", t.size);
    const int64_t capacity = t.is_vertex ? vertex_capacity(t.size) : signed_capacity(t.size);
    AMT_CHECK(t.entries <= capacity, s, ": ", t.field, ": expected a size whose indices reach all ", t.entries,
              " entries, found ", t.size, " (", capacity, " at most)");
  }

  const PmxVertices& v = m.vertices;
  const int64_t n = v.size();
  const auto check_rows = [&](const char* field, int64_t rows) {
    AMT_CHECK(rows == n, s, ": vertices.", field, ": expected ", n, " rows (one per position), found ", rows);
  };
  check_rows("normals", v.normals.rows());
  check_rows("uvs", v.uvs.rows());
  check_rows("deform", static_cast<int64_t>(v.deform.size()));
  check_rows("bone_indices", v.bone_indices.rows());
  check_rows("bone_weights", v.bone_weights.rows());
  check_rows("sdef_c", v.sdef_c.rows());
  check_rows("sdef_r0", v.sdef_r0.rows());
  check_rows("sdef_r1", v.sdef_r1.rows());
  check_rows("edge_scale", v.edge_scale.rows());
  AMT_CHECK(static_cast<int>(v.additional_uvs.size()) == h.additional_uv_count, s,
            ": vertices.additional_uvs: expected header.additional_uv_count = ", h.additional_uv_count,
            " matrices, found ", v.additional_uvs.size());
  for (const auto& extra : v.additional_uvs) check_rows("additional_uvs", extra.rows());
  for (size_t i = 0; i < v.deform.size(); ++i) {
    AMT_CHECK(static_cast<int>(v.deform[i]) <= static_cast<int>(PmxDeform::kQdef), s, ": vertices[", i,
              "].deform: expected 0 (BDEF1) to 4 (QDEF), found ", int(v.deform[i]));
  }
}

// === The writer

int deform_bone_count(PmxDeform deform) {
  return deform == PmxDeform::kBdef1 ? 1 : (deform == PmxDeform::kBdef2 || deform == PmxDeform::kSdef) ? 2 : 4;
}

class PmxWriter {
 public:
  PmxWriter(const PmxModel& model, PmxFieldOffsets* offsets)
      : m_(model), h_(model.header), out_(h_), offsets_(offsets) {}

  std::vector<uint8_t> write() {
    header();
    vertices();
    faces();
    textures_and_materials();
    bones();
    morphs_and_display_frames();
    rigid_bodies();
    joints();
    mark("end_of_joints");
    if (h_.version == 2.1f) {
      mark("soft_bodies");
      out_.i32(0);
    }
    return std::move(out_.bytes);
  }

 private:
  void mark(const PmxField& field) {
    if (offsets_) (*offsets_)[field.str()] = out_.bytes.size();
  }
  // Index fields are all marked.
  void bone_index(int32_t v, const PmxField& field) {
    mark(field);
    out_.index(v, h_.bone_index_size, field);
  }
  void body_index(int32_t v, const PmxField& field) {
    mark(field);
    out_.index(v, h_.rigid_body_index_size, field);
  }
  // The Japanese and the universal (English) name of a bone, rigid body or joint.
  template <typename Element>
  void names(const Element& e) {
    out_.text(e.name);
    out_.text(e.name_english);
  }
  void count(const char* section, size_t n) {
    mark(section);
    out_.i32(static_cast<int32_t>(n));
  }

  void header() {
    for (char c : std::string_view("PMX ")) out_.u8(static_cast<uint8_t>(c));
    out_.f32(h_.version);
    out_.u8(8);  // globals: encoding, additional uvs and the six index sizes
    out_.u8(static_cast<uint8_t>(h_.encoding));
    out_.u8(static_cast<uint8_t>(h_.additional_uv_count));
    for (int size : {h_.vertex_index_size, h_.texture_index_size, h_.material_index_size, h_.bone_index_size,
                     h_.morph_index_size, h_.rigid_body_index_size}) {
      out_.u8(static_cast<uint8_t>(size));
    }
    out_.text(h_.name);
    out_.text(h_.name_english);
    out_.text(h_.comment);
    out_.text(h_.comment_english);
  }

  void vertices() {
    const PmxVertices& v = m_.vertices;
    count("vertices", static_cast<size_t>(v.size()));
    for (int i = 0; i < v.size(); ++i) {
      mark({"vertices", i, "position"});
      out_.vec3(v.positions.row(i));
      out_.vec3(v.normals.row(i));
      out_.f32(v.uvs(i, 0));
      out_.f32(v.uvs(i, 1));
      for (const auto& extra : v.additional_uvs) {
        for (int c = 0; c < 4; ++c) out_.f32(extra(i, c));
      }
      const PmxDeform deform = v.deform[static_cast<size_t>(i)];
      out_.u8(static_cast<uint8_t>(deform));
      mark({"vertices", i, "bones"});
      const int bones = deform_bone_count(deform);
      for (int k = 0; k < bones; ++k) bone_index(v.bone_indices(i, k), {"vertices", i, "bones", k});
      if (bones == 2) out_.f32(v.bone_weights(i, 0));  // the second weight is 1 - w
      if (bones == 4) {
        for (int k = 0; k < 4; ++k) out_.f32(v.bone_weights(i, k));
      }
      if (deform == PmxDeform::kSdef) {
        out_.vec3(v.sdef_c.row(i));
        out_.vec3(v.sdef_r0.row(i));
        out_.vec3(v.sdef_r1.row(i));
      }
      out_.f32(v.edge_scale[i]);
    }
  }

  void faces() {
    count("faces", 3 * static_cast<size_t>(m_.faces.rows()));
    for (int f = 0; f < m_.faces.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        mark({"faces", f, nullptr, k});  // index fields are all marked
        out_.vertex_index(m_.faces(f, k), {"faces", f, nullptr, k});
      }
    }
  }

  // The model's textures and materials; without materials, one drawing every face.
  void textures_and_materials() {
    count("textures", m_.textures.size());
    for (const std::string& path : m_.textures) out_.text(path);
    if (!m_.materials.empty()) {
      count("materials", m_.materials.size());
      for (size_t i = 0; i < m_.materials.size(); ++i) material(m_.materials[i], static_cast<int64_t>(i));
      return;
    }
    PmxMaterial grey;  // double-sided, ground shadow, casts and receives self-shadow; no edge; MMD's shared toon 1
    grey.name = "材質1";
    grey.name_english = "material";
    grey.diffuse = {0.8f, 0.8f, 0.8f, 1.0f};
    grey.specular_strength = 5;
    grey.ambient = {0.4f, 0.4f, 0.4f};
    grey.flags = 0x0F;
    grey.edge_colour = {0.0f, 0.0f, 0.0f, 1.0f};
    grey.edge_size = 1;
    grey.shared_toon = true;
    grey.toon = 0;  // toon01.bmp
    grey.face_count = static_cast<int32_t>(m_.faces.rows());
    count("materials", 1);
    material(grey, 0);
  }

  void material(const PmxMaterial& m, int64_t i) {
    names(m);
    for (int c = 0; c < 4; ++c) out_.f32(m.diffuse[c]);
    out_.vec3(m.specular);
    out_.f32(m.specular_strength);
    out_.vec3(m.ambient);
    out_.u8(m.flags);
    for (int c = 0; c < 4; ++c) out_.f32(m.edge_colour[c]);
    out_.f32(m.edge_size);
    out_.index(m.texture, h_.texture_index_size, {"materials", i, "texture"});
    out_.index(m.sphere_texture, h_.texture_index_size, {"materials", i, "sphere_texture"});
    out_.u8(static_cast<uint8_t>(m.sphere_mode));
    out_.u8(m.shared_toon ? 1 : 0);
    if (m.shared_toon) {
      out_.u8(static_cast<uint8_t>(m.toon));
    } else {
      out_.index(m.toon, h_.texture_index_size, {"materials", i, "toon"});
    }
    out_.text(m.memo);
    out_.i32(static_cast<int32_t>(3 * static_cast<int64_t>(m.face_count)));
  }

  void bones() {
    count("bones", m_.bones.size());
    for (size_t n = 0; n < m_.bones.size(); ++n) {
      const PmxBone& b = m_.bones[n];
      const int64_t i = static_cast<int64_t>(n);
      names(b);
      mark({"bones", i, "position"});
      out_.vec3(b.position);
      bone_index(b.parent, {"bones", i, "parent"});
      out_.i32(b.layer);
      out_.u16(b.flags);
      if (b.flags & kPmxBoneTailIsBone) {
        bone_index(b.tail_bone, {"bones", i, "tail_bone"});
      } else {
        out_.vec3(b.tail_offset);
      }
      if (b.flags & (kPmxBoneInheritRotation | kPmxBoneInheritTranslation)) {
        bone_index(b.inherit_parent, {"bones", i, "inherit_parent"});
        out_.f32(b.inherit_weight);
      }
      if (b.flags & kPmxBoneFixedAxis) out_.vec3(b.fixed_axis);
      if (b.flags & kPmxBoneLocalAxes) {
        out_.vec3(b.local_axis_x);
        out_.vec3(b.local_axis_z);
      }
      if (b.flags & kPmxBoneExternalParent) out_.i32(b.external_parent_key);
      if (b.flags & kPmxBoneIk) ik(i, b.ik);
    }
  }

  void ik(int64_t i, const PmxIk& ik) {
    bone_index(ik.target, {"bones", i, "ik.target"});
    out_.i32(ik.loop_count);
    out_.f32(ik.limit_angle);
    mark({"bones", i, "ik.links"});
    out_.i32(static_cast<int32_t>(ik.links.size()));
    for (size_t k = 0; k < ik.links.size(); ++k) {
      const PmxIkLink& link = ik.links[k];
      bone_index(link.bone, {"bones", i, "ik.links", static_cast<int64_t>(k), "bone"});
      out_.u8(link.has_limits ? 1 : 0);
      if (link.has_limits) {
        out_.vec3(link.limit_min);
        out_.vec3(link.limit_max);
      }
    }
  }

  // No morphs; MMD's two special display frames: "Root" with bone 0, and the empty expression frame.
  void morphs_and_display_frames() {
    count("morphs", 0);
    count("display_frames", 2);
    out_.text("Root");
    out_.text("Root");
    out_.u8(1);  // special
    out_.i32(m_.bones.empty() ? 0 : 1);
    if (!m_.bones.empty()) {
      out_.u8(0);  // a bone element
      bone_index(0, {"display_frames", 0, "elements", 0});
    }
    out_.text("表情");
    out_.text("Exp");
    out_.u8(1);
    out_.i32(0);
  }

  void rigid_bodies() {
    count("rigid_bodies", m_.rigid_bodies.size());
    for (size_t n = 0; n < m_.rigid_bodies.size(); ++n) {
      const PmxRigidBody& r = m_.rigid_bodies[n];
      const int64_t i = static_cast<int64_t>(n);
      names(r);
      bone_index(r.bone, {"rigid_bodies", i, "bone"});
      out_.u8(r.group);
      out_.u16(r.collision_mask);
      out_.u8(static_cast<uint8_t>(r.shape));
      mark({"rigid_bodies", i, "size"});
      out_.vec3(r.size);
      mark({"rigid_bodies", i, "position"});
      out_.vec3(r.position);
      out_.vec3(r.rotation);
      mark({"rigid_bodies", i, "mass"});
      for (float value : {r.mass, r.linear_damping, r.angular_damping, r.restitution, r.friction}) out_.f32(value);
      out_.u8(static_cast<uint8_t>(r.mode));
    }
  }

  void joints() {
    count("joints", m_.joints.size());
    for (size_t n = 0; n < m_.joints.size(); ++n) {
      const PmxJoint& j = m_.joints[n];
      const int64_t i = static_cast<int64_t>(n);
      names(j);
      out_.u8(static_cast<uint8_t>(j.type));
      body_index(j.rigid_body_a, {"joints", i, "rigid_body_a"});
      body_index(j.rigid_body_b, {"joints", i, "rigid_body_b"});
      mark({"joints", i, "position"});
      for (const Eigen::Vector3f* v : {&j.position, &j.rotation, &j.linear_min, &j.linear_max, &j.angular_min,
                                       &j.angular_max, &j.spring_linear, &j.spring_angular}) {
        out_.vec3(*v);
      }
    }
  }

  const PmxModel& m_;
  const PmxHeader& h_;
  PmxEncoder out_;
  PmxFieldOffsets* offsets_;
};

}  // namespace

// === Writing

namespace {

// `name` names the model in messages.
std::vector<uint8_t> encode(const PmxModel& model, const std::string& name, PmxFieldOffsets* offsets) {
  check_encodable(model, name);
  try {
    return PmxWriter(model, offsets).write();
  } catch (const Error& e) {
    fail(name, ": ", e.what());  // the encoder names the field; add the model
  }
}

}  // namespace

std::vector<uint8_t> pmx_to_bytes(const PmxModel& model, PmxFieldOffsets* offsets) {
  return encode(model, model.source.empty() ? "PMX model" : model.source, offsets);
}

void write_pmx(const PmxModel& model, const std::string& path) {
  const std::vector<uint8_t> bytes = encode(model, path, nullptr);
  parse_pmx(bytes.data(), bytes.size(), path + " (as written)");  // throws on what read_pmx would reject
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

void pmx_fit_index_sizes(PmxModel& model) {
  const auto signed_size = [](int64_t entries) {
    return entries <= signed_capacity(1) ? 1 : entries <= signed_capacity(2) ? 2 : 4;
  };
  PmxHeader& h = model.header;
  const int64_t vertices = model.vertices.size();
  h.vertex_index_size = vertices <= vertex_capacity(1) ? 1 : vertices <= vertex_capacity(2) ? 2 : 4;
  h.texture_index_size = signed_size(static_cast<int64_t>(model.textures.size()));
  h.material_index_size = signed_size(written_material_count(model));
  h.bone_index_size = signed_size(static_cast<int64_t>(model.bones.size()));
  h.morph_index_size = signed_size(0);
  h.rigid_body_index_size = signed_size(static_cast<int64_t>(model.rigid_bodies.size()));
}

}  // namespace amt
