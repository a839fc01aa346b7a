#pragma once
// A PMX 2.0 / 2.1 writer for tests, written independently of the reader (data_tools/formats/pmx_import.h): every
// field of a PmxModel to bytes, with the encoding and index sizes chosen, remembering where each field went so
// that tests can patch bytes. Test support only: the product reads PMX, it does not write it here.
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "data_tools/formats/pmx_import.h"

namespace amt::test {

// UTF-8 -> UTF-16LE (well-formed input only), written separately from the reader's decoder.
inline std::vector<uint8_t> utf16le(const std::string& s) {
  std::vector<uint8_t> out;
  const auto put = [&out](uint32_t u) {
    out.push_back(uint8_t(u & 0xFF));
    out.push_back(uint8_t(u >> 8));
  };
  for (size_t i = 0; i < s.size();) {
    const uint8_t lead = static_cast<uint8_t>(s[i]);
    const int length = lead < 0x80 ? 1 : lead < 0xE0 ? 2 : lead < 0xF0 ? 3 : 4;
    uint32_t cp = length == 1 ? lead : lead & (0x7F >> length);
    for (int k = 1; k < length; ++k) cp = cp << 6 | (static_cast<uint8_t>(s[i + k]) & 0x3F);
    i += static_cast<size_t>(length);
    if (cp >= 0x10000) {
      put(0xD800 + ((cp - 0x10000) >> 10));
      put(0xDC00 + ((cp - 0x10000) & 0x3FF));
    } else {
      put(cp);
    }
  }
  return out;
}

struct WriteOptions {
  float version = 2.0f;
  PmxTextEncoding encoding = PmxTextEncoding::kUtf16Le;
  int vertex_index_size = 2;
  int index_size = 2;            // texture, material, bone, morph and rigid body indices
  int extra_globals = 0;         // globals past the first 8 (PMX 2.1)
  bool skipped_sections = true;  // textures, materials, morphs, display frames (and 2.1 soft bodies)
};

// Bytes of a PMX file and the offset of each field it was asked to remember ("bones[3].parent").
struct Written {
  std::vector<uint8_t> bytes;
  std::map<std::string, size_t> offsets;
  int texture_count = 0, material_count = 0, morph_count = 0, display_frame_count = 0, soft_body_count = 0;
};

class PmxWriter {
 public:
  explicit PmxWriter(const WriteOptions& options) : o_(options) {}

  Written write(const PmxModel& m) {
    header(m);
    vertices(m);
    faces(m);
    skipped_before_bones(m);
    bones(m);
    skipped_after_bones(m);
    rigid_bodies(m);
    joints(m);
    mark("end_of_joints");
    if (o_.version > 2.05f && o_.skipped_sections) soft_bodies();
    return std::move(w_);
  }

 private:
  void mark(const std::string& field) { w_.offsets[field] = w_.bytes.size(); }
  void u8(int v) { w_.bytes.push_back(static_cast<uint8_t>(v)); }
  void u16(int v) {
    u8(v & 0xFF);
    u8((v >> 8) & 0xFF);
  }
  void i32(int64_t v) {
    const uint32_t u = static_cast<uint32_t>(v);
    for (int k = 0; k < 4; ++k) u8((u >> (8 * k)) & 0xFF);
  }
  void f32(float v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    i32(u);
  }
  void vec(const Eigen::Vector3f& v) {
    for (int k = 0; k < 3; ++k) f32(v[k]);
  }
  void text(const std::string& s) {
    const std::vector<uint8_t> bytes =
        o_.encoding == PmxTextEncoding::kUtf16Le ? utf16le(s) : std::vector<uint8_t>(s.begin(), s.end());
    i32(static_cast<int64_t>(bytes.size()));
    w_.bytes.insert(w_.bytes.end(), bytes.begin(), bytes.end());
  }
  void index(int32_t v) {
    if (o_.index_size == 1) {
      u8(static_cast<uint8_t>(static_cast<int8_t>(v)));
    } else if (o_.index_size == 2) {
      u16(static_cast<uint16_t>(static_cast<int16_t>(v)));
    } else {
      i32(v);
    }
  }
  void vertex_index(int32_t v) {
    if (o_.vertex_index_size == 1) {
      u8(v);
    } else if (o_.vertex_index_size == 2) {
      u16(v);
    } else {
      i32(v);
    }
  }
  static std::string at(const char* table, int i, const char* member) {
    return std::string(table) + "[" + std::to_string(i) + "]." + member;
  }

  void header(const PmxModel& m) {
    for (char c : std::string("PMX ")) u8(c);
    f32(o_.version);
    u8(8 + o_.extra_globals);
    u8(static_cast<int>(o_.encoding));
    u8(m.header.additional_uv_count);
    u8(o_.vertex_index_size);
    for (int k = 0; k < 5; ++k) u8(o_.index_size);
    for (int k = 0; k < o_.extra_globals; ++k) u8(0x5A);
    text(m.header.name);
    text(m.header.name_english);
    text(m.header.comment);
    text(m.header.comment_english);
  }

  void vertices(const PmxModel& m) {
    const PmxVertices& v = m.vertices;
    mark("vertices");
    i32(v.size());
    const bool remember = v.size() < 1000;
    for (int i = 0; i < v.size(); ++i) {
      if (remember) mark(at("vertices", i, "position"));
      vec(v.positions.row(i));
      vec(v.normals.row(i));
      f32(v.uvs(i, 0));
      f32(v.uvs(i, 1));
      for (int k = 0; k < m.header.additional_uv_count; ++k) {
        for (int c = 0; c < 4; ++c) f32(v.additional_uvs[static_cast<size_t>(k)](i, c));
      }
      const PmxDeform d = v.deform[static_cast<size_t>(i)];
      u8(static_cast<int>(d));
      if (remember) mark(at("vertices", i, "bones"));
      const int bones = d == PmxDeform::kBdef1 ? 1 : (d == PmxDeform::kBdef2 || d == PmxDeform::kSdef) ? 2 : 4;
      for (int k = 0; k < bones; ++k) index(v.bone_indices(i, k));
      if (bones == 2) f32(v.bone_weights(i, 0));
      if (bones == 4) {
        for (int k = 0; k < 4; ++k) f32(v.bone_weights(i, k));
      }
      if (d == PmxDeform::kSdef) {
        vec(v.sdef_c.row(i));
        vec(v.sdef_r0.row(i));
        vec(v.sdef_r1.row(i));
      }
      f32(v.edge_scale[i]);
    }
  }

  void faces(const PmxModel& m) {
    mark("faces");
    i32(3 * m.faces.rows());
    for (int f = 0; f < m.faces.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        if (f < 10) mark("faces[" + std::to_string(f) + "][" + std::to_string(k) + "]");
        vertex_index(m.faces(f, k));
      }
    }
  }

  void skipped_before_bones(const PmxModel& m) {
    const bool write = o_.skipped_sections;
    w_.texture_count = write ? 2 : 0;
    i32(w_.texture_count);
    if (write) {
      text("tex/body.png");
      text("toon/肌.bmp");
    }
    w_.material_count = write ? 2 : 0;
    mark("materials");
    i32(w_.material_count);
    for (int i = 0; i < w_.material_count; ++i) {
      text(i == 0 ? "肌" : "スカート");
      text(i == 0 ? "skin" : "skirt");
      for (int k = 0; k < 4 + 3 + 1 + 3; ++k) f32(0.25f * k);  // diffuse, specular, strength, ambient
      u8(0x1F);                                                // flags
      for (int k = 0; k < 4 + 1; ++k) f32(1);                  // edge colour, edge size
      index(0);                                                // texture
      index(-1);                                               // sphere texture
      u8(1);                                                   // sphere mode
      u8(i);                                                   // toon: 0 texture index, 1 shared toon byte
      if (i == 0) {
        index(1);
      } else {
        u8(3);
      }
      text("memo");
      i32(i == 0 ? 3 : 3 * (m.faces.rows() - 1));
    }
  }

  void bones(const PmxModel& m) {
    mark("bones");
    i32(static_cast<int64_t>(m.bones.size()));
    for (size_t n = 0; n < m.bones.size(); ++n) {
      const PmxBone& b = m.bones[n];
      const int i = static_cast<int>(n);
      text(b.name);
      text(b.name_english);
      vec(b.position);
      mark(at("bones", i, "parent"));
      index(b.parent);
      i32(b.layer);
      u16(b.flags);
      if (b.flags & 0x0001) {
        index(b.tail_bone);
      } else {
        vec(b.tail_offset);
      }
      if (b.flags & 0x0300) {
        mark(at("bones", i, "inherit_parent"));
        index(b.inherit_parent);
        f32(b.inherit_weight);
      }
      if (b.flags & 0x0400) vec(b.fixed_axis);
      if (b.flags & 0x0800) {
        vec(b.local_axis_x);
        vec(b.local_axis_z);
      }
      if (b.flags & 0x2000) i32(b.external_parent_key);
      if (b.flags & 0x0020) {
        mark(at("bones", i, "ik.target"));
        index(b.ik.target);
        i32(b.ik.loop_count);
        f32(b.ik.limit_angle);
        mark(at("bones", i, "ik.links"));
        i32(static_cast<int64_t>(b.ik.links.size()));
        for (const PmxIkLink& link : b.ik.links) {
          index(link.bone);
          u8(link.has_limits ? 1 : 0);
          if (link.has_limits) {
            vec(link.limit_min);
            vec(link.limit_max);
          }
        }
      }
    }
  }

  void skipped_after_bones(const PmxModel& m) {
    const bool v21 = o_.version > 2.05f;
    const int types = o_.skipped_sections ? (v21 ? 11 : 9) : 0;
    w_.morph_count = types;
    mark("morphs");
    i32(types);
    for (int t = 0; t < types; ++t) {
      text("モーフ" + std::to_string(t));
      text("morph " + std::to_string(t));
      u8(t % 5);  // panel
      u8(t);      // type
      i32(2);     // offsets
      for (int k = 0; k < 2; ++k) {
        switch (t) {
          case 0:  // group
          case 9:  // flip
            index(0);
            f32(0.5f);
            break;
          case 1:  // vertex
            vertex_index(1);
            vec(Eigen::Vector3f(0.1f, 0.2f, 0.3f));
            break;
          case 2:  // bone
            index(1);
            vec(Eigen::Vector3f(0, 1, 0));
            for (int c = 0; c < 4; ++c) f32(c == 3 ? 1.0f : 0.0f);
            break;
          case 8:  // material
            index(-1);
            u8(1);
            for (int c = 0; c < 28; ++c) f32(1);
            break;
          case 10:  // impulse
            index(0);
            u8(1);
            vec(Eigen::Vector3f(1, 2, 3));
            vec(Eigen::Vector3f(4, 5, 6));
            break;
          default:  // uv and additional uv
            vertex_index(2);
            for (int c = 0; c < 4; ++c) f32(0.125f);
        }
      }
    }
    w_.display_frame_count = o_.skipped_sections ? 2 : 0;
    i32(w_.display_frame_count);
    for (int i = 0; i < w_.display_frame_count; ++i) {
      text(i == 0 ? "Root" : "表情");
      text(i == 0 ? "Root" : "Exp");
      u8(1);
      i32(2);
      u8(0);  // bone element
      index(static_cast<int32_t>(m.bones.size()) - 1);
      u8(1);  // morph element
      index(0);
    }
  }

  void rigid_bodies(const PmxModel& m) {
    mark("rigid_bodies");
    i32(static_cast<int64_t>(m.rigid_bodies.size()));
    for (size_t n = 0; n < m.rigid_bodies.size(); ++n) {
      const PmxRigidBody& r = m.rigid_bodies[n];
      const int i = static_cast<int>(n);
      text(r.name);
      text(r.name_english);
      mark(at("rigid_bodies", i, "bone"));
      index(r.bone);
      u8(r.group);
      u16(r.collision_mask);
      u8(static_cast<int>(r.shape));
      mark(at("rigid_bodies", i, "size"));
      vec(r.size);
      vec(r.position);
      vec(r.rotation);
      mark(at("rigid_bodies", i, "mass"));
      f32(r.mass);
      f32(r.linear_damping);
      f32(r.angular_damping);
      f32(r.restitution);
      f32(r.friction);
      u8(static_cast<int>(r.mode));
    }
  }

  void joints(const PmxModel& m) {
    mark("joints");
    i32(static_cast<int64_t>(m.joints.size()));
    for (size_t n = 0; n < m.joints.size(); ++n) {
      const PmxJoint& j = m.joints[n];
      const int i = static_cast<int>(n);
      text(j.name);
      text(j.name_english);
      u8(static_cast<int>(j.type));
      mark(at("joints", i, "rigid_body_a"));
      index(j.rigid_body_a);
      mark(at("joints", i, "rigid_body_b"));
      index(j.rigid_body_b);
      for (const Eigen::Vector3f* v : {&j.position, &j.rotation, &j.linear_min, &j.linear_max, &j.angular_min,
                                       &j.angular_max, &j.spring_linear, &j.spring_angular}) {
        vec(*v);
      }
    }
  }

  void soft_bodies() {
    w_.soft_body_count = 1;
    i32(1);
    text("スカート布");
    text("skirt cloth");
    u8(0);                                           // shape: triangle mesh
    index(1);                                        // material
    u8(2);                                           // group
    u16(0xFFFB);                                     // mask
    u8(0x03);                                        // flags
    i32(2);                                          // B-link distance
    i32(4);                                          // clusters
    f32(1.5f);                                       // total mass
    f32(0.05f);                                      // margin
    i32(1);                                          // aerodynamics model
    for (int k = 0; k < 12 + 6; ++k) f32(0.1f * k);  // config, cluster
    for (int k = 0; k < 4; ++k) i32(k + 1);          // iterations
    for (int k = 0; k < 3; ++k) f32(1);              // material
    i32(2);                                          // anchors
    for (int k = 0; k < 2; ++k) {
      index(k);
      vertex_index(k);
      u8(k);
    }
    i32(3);  // pins
    for (int k = 0; k < 3; ++k) vertex_index(k);
  }

  WriteOptions o_;
  Written w_;
};

/// The bytes of `m` as a PMX file with the choices of `o`.
inline Written write_test_pmx(const PmxModel& m, const WriteOptions& o = {}) {
  return PmxWriter(o).write(m);
}

/// Writes `m` to `path` as a PMX file (test input).
inline void write_test_pmx_file(const PmxModel& m, const std::string& path, const WriteOptions& o = {}) {
  const Written w = write_test_pmx(m, o);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(w.bytes.data()), static_cast<std::streamsize>(w.bytes.size()));
}

}  // namespace amt::test
