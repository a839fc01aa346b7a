#pragma once
// PMX 2.0 / 2.1 writer: the inverse of data_tools/formats/pmx_import.h for every field a PmxModel holds (header
// names, vertices with their BDEF1 / BDEF2 / BDEF4 / SDEF / QDEF weights as the model has them, faces, texture
// paths and materials, bones with parents, flags, tails, inheritance, axes and IK, rigid bodies, joints). Real MMD
// characters cannot be shipped with amt, so the tests and `amt dataset export-pmx` make their PMX files with it.
//
// The file is written as model.header says: its version, text encoding, additional uv count and index sizes
// (pmx_fit_index_sizes picks the smallest sizes that hold the model). A model without materials gets one drawing
// every face (grey, double-sided, MMD's shared toon 1). The sections a PmxModel only counts are written as a
// minimal valid model needs them, whatever the counts say: no morphs; MMD's two special display frames, "Root"
// holding bone 0 and "表情" (expressions) empty; and, in 2.1, no soft bodies. Reading the bytes back with parse_pmx
// gives the same model field for field (plus the grey material where there was none), so write -> read -> write
// gives the same bytes.
//
// The model is written in the frame its fields are in: a PMX file holds PmxFrame::kMmd values, so a model in
// amt's frame is refused (there is no inverse of pmx_to_amt_frame here; data_tools/builder/pmx_character_export.h
// builds models in MMD's frame directly).
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "data_tools/formats/pmx_field.h"
#include "data_tools/formats/pmx_import.h"

namespace amt {

// === Encoding

/// UTF-8 text as UTF-16LE bytes (code points above U+FFFF as surrogate pairs). Ill-formed UTF-8 is first replaced
/// as sanitize_utf8 does (data_tools/formats/pmx_import.h).
std::vector<uint8_t> utf8_to_utf16le(const std::string& text);

/// Appends PMX's little-endian primitives to `bytes`: numbers, texts in the header's encoding, indices of the
/// header's sizes. The writer is built on it; tests use it to add sections a PmxModel does not hold.
class PmxEncoder {
 public:
  /// Encodes texts and vertex indices as `header` says (copied).
  explicit PmxEncoder(const PmxHeader& header) : header_(header) {}

  void u8(uint8_t v) { bytes.push_back(v); }
  void u16(uint16_t v);
  void i32(int32_t v);
  void f32(float v);
  void vec3(const Eigen::Vector3f& v);
  /// An int32 byte length, then the UTF-8 text in the header's encoding: UTF-16LE (utf8_to_utf16le) or UTF-8
  /// written byte for byte (ill-formed bytes included, for the reader's tests).
  void text(const std::string& utf8);
  /// A signed index of `size` bytes (1, 2 or 4: the header's texture, material, bone, morph or rigid body index
  /// size; -1 is "none"). Throws amt::Error naming `field` if the value does not fit that size (-128..127 for 1
  /// byte, -32768..32767 for 2).
  void index(int32_t v, int size, const PmxField& field);
  /// A vertex index of header.vertex_index_size bytes (unsigned for 1 and 2, signed for 4). Throws amt::Error
  /// naming `field` if the value does not fit.
  void vertex_index(int32_t v, const PmxField& field);

  /// The bytes written so far.
  std::vector<uint8_t> bytes;

 private:
  PmxHeader header_;
};

/// Euler angles (radians) of a rotation in PMX's composition R = Ry(y) Rx(x) Rz(z): the inverse of
/// pmx_euler_rotation (data_tools/formats/pmx_import.h), x in [-pi/2, pi/2], y and z in (-pi, pi]. At x = +-pi/2
/// only y - z or y + z is defined; z = 0 is returned then.
Eigen::Vector3f pmx_euler_angles(const Eigen::Matrix3f& R);

// === Writing

/// Byte offsets of fields in written bytes, by the reader's field names: each section's count ("vertices",
/// "faces", "textures", "materials", "bones", "morphs", "display_frames", "rigid_bodies", "joints", and
/// "soft_bodies" in 2.1), "end_of_joints", every index field ("faces[f][k]", "vertices[i].bones[k]",
/// "bones[i].parent", "bones[i].ik.target", "rigid_bodies[i].bone", "joints[i].rigid_body_a", ...), and
/// "vertices[i].position", "vertices[i].bones" (the first bone index), "bones[i].position", "bones[i].ik.links",
/// "rigid_bodies[i].size", "rigid_bodies[i].position", "rigid_bodies[i].mass", "joints[i].position". For tests
/// that damage a file at a known field.
using PmxFieldOffsets = std::map<std::string, size_t>;

/// The PMX file of `model` as bytes; fills `offsets` when given. Encodes what fits the format, also indices
/// outside their tables (so that tests can make malformed files); throws amt::Error with one line
/// "source: field: expected ..., found ..." on what cannot be encoded: a model in amt's frame, a version other
/// than 2.0 / 2.1, an index size other than 1, 2, 4 or too small for its table, an index that does not fit its
/// size, per-vertex arrays of the wrong size, more than 4 additional uvs.
std::vector<uint8_t> pmx_to_bytes(const PmxModel& model, PmxFieldOffsets* offsets = nullptr);

/// Writes the model to `path` atomically (data_tools/formats/atomic_file.h: a temporary file renamed onto the
/// path). The bytes are first read back with parse_pmx, so that only a file read_pmx accepts reaches the disk:
/// a model it would reject (an index outside its table, a parent cycle, a non-finite number) is an amt::Error
/// "path (as written): offset N: field: expected ..., found ..." and nothing is written.
void write_pmx(const PmxModel& model, const std::string& path);

/// Sets the header's index sizes to the smallest that hold the model's tables: vertex indices 1 byte below 256
/// vertices, 2 below 65536, else 4; the other indices (signed, -1 for none) 1 byte up to 128 entries, 2 up to
/// 32768, else 4 (materials: at least the one material the writer writes).
void pmx_fit_index_sizes(PmxModel& model);

}  // namespace amt
