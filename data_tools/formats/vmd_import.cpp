// VMD reader and writer. The layout, little-endian throughout, as documented by:
//   - the MMD wiki / VPVP wiki notes on the format ("VMDファイルフォーマット", https://w.atwiki.jp/kumiho_k/ and
//     the MikuMikuDance format notes mirrored at https://mikumikudance.fandom.com/wiki/VMD_file_format);
//   - blender_mmd_tools (github.com/UuuNyaa/blender_mmd_tools, mmd_tools/core/vmd/__init__.py: Header,
//     BoneFrameKey, ShapeKeyFrameKey, CameraKeyFrameKey, LampKeyFrameKey, SelfShadowFrameKey,
//     PropertyFrameKey) and its importer (mmd_tools/core/vmd/importer.py, the interpolation block);
//   - saba (github.com/benikabocha/saba, src/Saba/Model/MMD/VMDFile.cpp and VMDAnimation.cpp: the Bézier
//     evaluation and which keyframe's curve applies).
//
//   header        30 bytes  "Vocaloid Motion Data 0002" (version 2) or "Vocaloid Motion Data file" (version 1),
//                           NUL-padded
//   model name    20 bytes (version 2) or 10 bytes (version 1), Shift-JIS, NUL-terminated within the field
//   bone keys     uint32 count, then per key 111 bytes:
//                   name 15 bytes Shift-JIS, frame uint32, position float x3, rotation quaternion float x4
//                   (x, y, z, w), interpolation 64 bytes
//   morph keys    uint32 count, 23 bytes each (name 15, frame uint32, weight float)
//   camera keys   uint32 count, 61 bytes each (frame, distance, position x3, rotation x3, interpolation 24, view
//                 angle uint32, perspective uint8)
//   light keys    uint32 count, 28 bytes each (frame, colour x3, direction x3)
//   self shadow   uint32 count, 9 bytes each (frame, mode uint8, distance float)
//   IK enable     uint32 count, per key: frame uint32, visible uint8, uint32 n, n x (IK bone name 20 bytes,
//                 enabled uint8)
// Any section after the bone keys may be missing: the file then ends after the previous complete section.
//
// The interpolation block: its first 16 bytes hold the four curves X, Y, Z and rotation as
//   x1 = b[a], y1 = b[a + 4], x2 = b[a + 8], y2 = b[a + 12]   for axis a = 0 (X), 1 (Y), 2 (Z), 3 (rotation);
// the other 48 bytes repeat them shifted by one byte per row (MMD's own redundancy) and are not read.
#include "data_tools/formats/vmd_import.h"

#include <iconv.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>

#include "data_tools/formats/input_file.h"
#include "data_tools/geometry/error.h"

namespace amt {
namespace {

constexpr char kHeader2[] = "Vocaloid Motion Data 0002";
constexpr char kHeader1[] = "Vocaloid Motion Data file";
constexpr size_t kHeaderBytes = 30;
constexpr size_t kBoneKeyBytes = 111;
constexpr size_t kMorphKeyBytes = 23;
constexpr size_t kCameraKeyBytes = 61;
constexpr size_t kLightKeyBytes = 28;
constexpr size_t kSelfShadowKeyBytes = 9;
constexpr size_t kIkNameBytes = 20;
constexpr size_t kInterpolationBytes = 64;

// iconv descriptors in an RAII wrapper; glibc calls the Windows code page "CP932" (Shift-JIS with Microsoft's
// extensions, what MMD writes), plain "SHIFT_JIS" is the fallback.
struct IconvCloser {
  void operator()(void* cd) const { iconv_close(static_cast<iconv_t>(cd)); }
};
using IconvHandle = std::unique_ptr<void, IconvCloser>;

IconvHandle open_iconv(const char* to, const char* from) {
  iconv_t cd = iconv_open(to, from);
  if (cd == reinterpret_cast<iconv_t>(-1) && std::strcmp(to, "CP932") == 0) cd = iconv_open("SHIFT_JIS", from);
  if (cd == reinterpret_cast<iconv_t>(-1) && std::strcmp(from, "CP932") == 0) cd = iconv_open(to, "SHIFT_JIS");
  AMT_CHECK(cd != reinterpret_cast<iconv_t>(-1), "Shift-JIS text: expected iconv to convert ", from, " to ", to,
            ", found no such conversion in the C library");
  return IconvHandle(cd);
}

// Converts `in` with `cd`; an invalid sequence becomes `replacement` and its first byte is skipped; a sequence cut
// by the end of the input is dropped.
std::string convert(void* cd_ptr, const char* in, size_t size, const std::string& replacement) {
  iconv_t cd = static_cast<iconv_t>(cd_ptr);
  iconv(cd, nullptr, nullptr, nullptr, nullptr);
  std::string out;
  char buffer[256];
  char* src = const_cast<char*>(in);
  size_t left = size;
  while (left > 0) {
    char* dst = buffer;
    size_t room = sizeof buffer;
    const size_t r = iconv(cd, &src, &left, &dst, &room);
    out.append(buffer, static_cast<size_t>(dst - buffer));
    if (r != static_cast<size_t>(-1)) continue;
    if (errno == E2BIG) continue;
    if (errno == EINVAL) break;  // incomplete character at the end of the field
    out += replacement;          // EILSEQ
    ++src;
    --left;
  }
  return out;
}

// Bounds-checked little-endian reader over the file's bytes; every failure names the file and the field.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size, const std::string& source) : data_(data), size_(size), source_(source) {}

  size_t left() const { return size_ - at_; }
  size_t offset() const { return at_; }

  void need(size_t bytes, const std::string& field) const {
    AMT_CHECK(bytes <= left(), source_, ": ", field, ": expected ", bytes, " more bytes at offset ", at_, ", found ",
              left(), " (truncated file)");
  }
  const uint8_t* bytes(size_t n, const std::string& field) {
    need(n, field);
    const uint8_t* p = data_ + at_;
    at_ += n;
    return p;
  }
  uint32_t u32(const std::string& field) {
    const uint8_t* p = bytes(4, field);
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
  }
  float f32(const std::string& field) {
    const uint32_t bits = u32(field);
    float v;
    std::memcpy(&v, &bits, 4);
    AMT_CHECK(std::isfinite(v), source_, ": ", field, ": expected a finite number, found ", v);
    return v;
  }
  // A section count, checked against the bytes left: each record takes at least `record_bytes`.
  uint32_t count(const std::string& field, size_t record_bytes) {
    const uint32_t n = u32(field);
    AMT_CHECK(uint64_t(n) * record_bytes <= left(), source_, ": ", field, ": expected at most ", left() / record_bytes,
              " (records of at least ", record_bytes, " bytes in the ", left(), " bytes left), found ", n);
    return n;
  }
  void skip(size_t n, const std::string& field) { bytes(n, field); }

 private:
  const uint8_t* data_;
  size_t size_;
  const std::string& source_;
  size_t at_ = 0;
};

uint8_t clamp_control(uint8_t v) {
  return std::min<uint8_t>(v, 127);
}

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
}

void put_f32(std::vector<uint8_t>& out, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, 4);
  put_u32(out, bits);
}

// `text` encoded and cut to `field` bytes without splitting a double-byte character, NUL-padded.
void put_name(std::vector<uint8_t>& out, const std::string& utf8, size_t field) {
  const std::string sjis = utf8_to_shift_jis(utf8);
  size_t n = 0;
  for (size_t i = 0; i < sjis.size();) {
    const uint8_t c = uint8_t(sjis[i]);
    const size_t width = ((c >= 0x81 && c <= 0x9F) || (c >= 0xE0 && c <= 0xFC)) ? 2 : 1;
    if (i + width > field) break;
    i += width;
    n = i;
  }
  out.insert(out.end(), sjis.begin(), sjis.begin() + std::ptrdiff_t(n));
  out.insert(out.end(), field - n, uint8_t(0));
}

}  // namespace

// === Text

std::string shift_jis_to_utf8(const uint8_t* bytes, size_t size) {
  const size_t n = static_cast<size_t>(std::find(bytes, bytes + size, uint8_t(0)) - bytes);
  static thread_local IconvHandle cd = open_iconv("UTF-8", "CP932");
  return convert(cd.get(), reinterpret_cast<const char*>(bytes), n, "\xEF\xBF\xBD");
}

std::string utf8_to_shift_jis(const std::string& text) {
  static thread_local IconvHandle cd = open_iconv("CP932", "UTF-8");
  return convert(cd.get(), text.data(), text.size(), "?");
}

std::string vmd_field_name(const std::string& name, size_t field_bytes) {
  std::vector<uint8_t> field;
  put_name(field, name, field_bytes);
  return shift_jis_to_utf8(field.data(), field.size());
}

// === Motion

uint32_t VmdMotion::last_frame() const {
  uint32_t last = 0;
  for (const VmdBoneKey& k : bone_keys) last = std::max(last, k.frame);
  return last;
}

std::string VmdMotion::ignored_note() const {
  std::vector<std::string> kinds;
  const std::pair<const char*, uint32_t> tracks[] = {{"morph", morph_keys},
                                                     {"camera", camera_keys},
                                                     {"light", light_keys},
                                                     {"self-shadow", self_shadow_keys},
                                                     {"IK-enable", ik_keys}};
  uint64_t total = 0;
  for (const auto& [name, n] : tracks) {
    if (n == 0) continue;
    kinds.push_back(name);
    total += n;
  }
  if (kinds.empty()) return "";
  std::string list;
  for (size_t i = 0; i < kinds.size(); ++i) list += (i == 0 ? "" : i + 1 == kinds.size() ? " and " : ", ") + kinds[i];
  return detail::concat(list, kinds.size() == 1 ? " track" : " tracks", " ignored (", total,
                        total == 1 ? " keyframe)" : " keyframes)");
}

// === Reading and writing

VmdMotion parse_vmd(const uint8_t* data, size_t size, const std::string& source) {
  Reader r(data, size, source);
  VmdMotion m;
  m.source = source;
  const uint8_t* header = r.bytes(kHeaderBytes, "header");
  const std::string magic(reinterpret_cast<const char*>(header),
                          std::find(header, header + kHeaderBytes, uint8_t(0)) - header);
  if (magic == kHeader2) {
    m.version = 2;
  } else if (magic == kHeader1) {
    m.version = 1;
  } else {
    std::string shown;
    for (const char c : magic.substr(0, 30)) shown += (c >= 32 && c < 127) ? c : '?';
    fail(source, ": header: expected \"", kHeader2, "\" or \"", kHeader1, "\" (a VMD motion), found \"", shown, "\"");
  }
  const size_t name_bytes = m.version == 2 ? 20 : 10;
  m.model_name = shift_jis_to_utf8(r.bytes(name_bytes, "model name"), name_bytes);

  const uint32_t bones = r.count("bone keyframe count", kBoneKeyBytes);
  m.bone_keys.resize(bones);
  for (uint32_t i = 0; i < bones; ++i) {
    const std::string field = detail::concat("bone keyframe ", i);
    VmdBoneKey& k = m.bone_keys[i];
    k.bone = shift_jis_to_utf8(r.bytes(kVmdBoneNameBytes, field + " name"), kVmdBoneNameBytes);
    k.frame = r.u32(field + " frame");
    for (int a = 0; a < 3; ++a) k.translation[a] = r.f32(field + " position");
    float q[4];
    for (float& v : q) v = r.f32(field + " rotation");
    const float norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    AMT_CHECK(norm > 1e-6f, source, ": ", field, " rotation: expected a non-zero quaternion, found (", q[0], ", ", q[1],
              ", ", q[2], ", ", q[3], ")");
    k.rotation = Eigen::Quaternionf(q[3], q[0], q[1], q[2]).normalized();
    const uint8_t* b = r.bytes(kInterpolationBytes, field + " interpolation");
    for (int a = 0; a < 4; ++a) {
      k.curves[size_t(a)] = {clamp_control(b[a]), clamp_control(b[a + 4]), clamp_control(b[a + 8]),
                             clamp_control(b[a + 12])};
    }
  }

  // The optional tracks: counted, checked for size and skipped.
  struct Track {
    const char* name;
    size_t bytes;
    uint32_t* count;
  };
  for (const Track& track :
       {Track{"morph", kMorphKeyBytes, &m.morph_keys}, Track{"camera", kCameraKeyBytes, &m.camera_keys},
        Track{"light", kLightKeyBytes, &m.light_keys},
        Track{"self-shadow", kSelfShadowKeyBytes, &m.self_shadow_keys}}) {
    if (r.left() == 0) return m;
    *track.count = r.count(detail::concat(track.name, " keyframe count"), track.bytes);
    r.skip(size_t(*track.count) * track.bytes, detail::concat(track.name, " keyframes"));
  }
  if (r.left() == 0) return m;
  m.ik_keys = r.count("IK keyframe count", 9);
  for (uint32_t i = 0; i < m.ik_keys; ++i) {
    const std::string field = detail::concat("IK keyframe ", i);
    r.skip(5, field);
    const uint32_t n = r.count(field + " IK bone count", kIkNameBytes + 1);
    r.skip(size_t(n) * (kIkNameBytes + 1), field + " IK bones");
  }
  return m;
}

VmdMotion read_vmd(const std::string& path) {
  const uint64_t size = check_input_file(path, "a VMD motion");
  std::ifstream file(path, std::ios::binary);
  AMT_CHECK(file, path, ": cannot open the file for reading");
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  file.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(size));
  AMT_CHECK(uint64_t(file.gcount()) == size, path, ": read error after ", file.gcount(), " of ", size, " bytes");
  return parse_vmd(bytes.data(), bytes.size(), path);
}

std::vector<uint8_t> vmd_bytes(const VmdMotion& motion) {
  std::vector<uint8_t> out;
  put_name(out, kHeader2, kHeaderBytes);
  put_name(out, motion.model_name, 20);
  put_u32(out, uint32_t(motion.bone_keys.size()));
  for (const VmdBoneKey& k : motion.bone_keys) {
    put_name(out, k.bone, kVmdBoneNameBytes);
    put_u32(out, k.frame);
    for (int a = 0; a < 3; ++a) put_f32(out, k.translation[a]);
    put_f32(out, k.rotation.x());
    put_f32(out, k.rotation.y());
    put_f32(out, k.rotation.z());
    put_f32(out, k.rotation.w());
    uint8_t row[16];
    for (int a = 0; a < 4; ++a) {
      const VmdCurve& c = k.curves[size_t(a)];
      row[a] = c.x1;
      row[a + 4] = c.y1;
      row[a + 8] = c.x2;
      row[a + 12] = c.y2;
    }
    // Rows 1 to 3 repeat row 0 shifted by one byte each, as MMD writes them.
    for (int shift = 0; shift < 4; ++shift) {
      for (int i = 0; i < 16; ++i) out.push_back(i + shift < 16 ? row[i + shift] : uint8_t(0));
    }
  }
  for (int section = 0; section < 5; ++section) put_u32(out, 0);  // morph, camera, light, self shadow, IK
  return out;
}

void write_vmd(const VmdMotion& motion, const std::string& path) {
  const std::vector<uint8_t> bytes = vmd_bytes(motion);
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  AMT_CHECK(file, path, ": cannot open the file for writing");
  file.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  AMT_CHECK(file.good(), path, ": write error");
}

// === Interpolation

float vmd_bezier_weight(uint8_t x1, uint8_t y1, uint8_t x2, uint8_t y2, float t) {
  t = std::clamp(t, 0.0f, 1.0f);
  if (x1 == y1 && x2 == y2) return t;  // the curve is the diagonal
  const double ax = std::min<int>(x1, 127) / 127.0, bx = std::min<int>(x2, 127) / 127.0;
  const double ay = std::min<int>(y1, 127) / 127.0, by = std::min<int>(y2, 127) / 127.0;
  // B(s) = 3 (1 - s)^2 s P1 + 3 (1 - s) s^2 P2 + s^3, monotone in x for control x in [0, 1].
  const auto bezier = [](double p1, double p2, double s) {
    const double u = 1 - s;
    return 3 * u * u * s * p1 + 3 * u * s * s * p2 + s * s * s;
  };
  double lo = 0, hi = 1;
  while (hi - lo > 1e-7) {
    const double s = 0.5 * (lo + hi);
    (bezier(ax, bx, s) < t ? lo : hi) = s;
  }
  return float(bezier(ay, by, 0.5 * (lo + hi)));
}

std::map<std::string, std::vector<VmdBoneKey>> vmd_bone_tracks(const VmdMotion& motion) {
  std::map<std::string, std::vector<VmdBoneKey>> tracks;
  for (const VmdBoneKey& k : motion.bone_keys) tracks[k.bone].push_back(k);
  for (auto& [name, keys] : tracks) {
    std::stable_sort(keys.begin(), keys.end(),
                     [](const VmdBoneKey& a, const VmdBoneKey& b) { return a.frame < b.frame; });
    // Of keys on one frame keep the last in the file.
    std::vector<VmdBoneKey> unique;
    for (const VmdBoneKey& k : keys) {
      if (!unique.empty() && unique.back().frame == k.frame)
        unique.back() = k;
      else
        unique.push_back(k);
    }
    keys = std::move(unique);
  }
  return tracks;
}

VmdBonePose vmd_sample(const std::vector<VmdBoneKey>& track, float frame) {
  AMT_CHECK(!track.empty(), "VMD track: expected at least one key, found none");
  VmdBonePose p;
  const auto after = std::upper_bound(track.begin(), track.end(), frame,
                                      [](float f, const VmdBoneKey& k) { return f < float(k.frame); });
  if (after == track.begin() || after == track.end()) {
    const VmdBoneKey& k = after == track.begin() ? track.front() : track.back();
    p.translation = k.translation;
    p.rotation = k.rotation;
    return p;
  }
  const VmdBoneKey& a = *(after - 1);
  const VmdBoneKey& b = *after;
  const float t = (frame - float(a.frame)) / float(b.frame - a.frame);
  for (int axis = 0; axis < 3; ++axis) {
    const VmdCurve& c = b.curves[size_t(axis)];
    const float w = vmd_bezier_weight(c.x1, c.y1, c.x2, c.y2, t);
    p.translation[axis] = a.translation[axis] + w * (b.translation[axis] - a.translation[axis]);
  }
  const VmdCurve& c = b.curves[kVmdCurveRotation];
  p.rotation = a.rotation.slerp(vmd_bezier_weight(c.x1, c.y1, c.x2, c.y2, t), b.rotation).normalized();
  return p;
}

}  // namespace amt
