#pragma once
// The bind cache (issue 6, item 2): the result of bind_character (models/pipeline.h), stored in one
// file so that animating the same character again skips segmentation, geodesics, skinning weights and
// the apparel graph. The file is keyed by a hash of everything the bind depends on: the rest mesh,
// the rest joints, an apparel-mask override, and the bytes of the model's checkpoint files. A changed
// mesh or model gives another key, and the stale file is recomputed and replaced.
//
// File: a torch::serialize archive (TorchScript zip) with format "amt-bind", version kBindVersion, the key, and
// one tensor per BoundCharacter field (the hung pieces' two counts as one int64 tensor), and a CRC-32 of all of
// it; written to "<path>.amt-tmp" and renamed.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/geometry/mesh.h"
#include "models/pipeline.h"

namespace amt {

/// Value of the archive key `format`, and the version written and read.
inline constexpr const char* kBindFormat = "amt-bind";
inline constexpr int64_t kBindVersion = 9;  // 4: apparel pieces hung (hang_apparel_pieces); 5: and what it changed;
                                            // 6: the linked topology and the handles; 7: the apparel
                                            // bones' physics response; 8: the swing calibration;
                                            // 9: each side of a weld group across the mask tied

/// FNV-1a 64-bit over bytes, continuing from `hash` (start with kFnvOffset).
inline constexpr uint64_t kFnvOffset = 14695981039346656037ull;
uint64_t fnv1a64(const void* data, size_t size, uint64_t hash = kFnvOffset);

/// fnv1a64 over the bytes of the regular file `path` (`what` names it in the error), continuing from `hash`. Throws
/// amt::Error when it cannot be read.
uint64_t fnv1a64_file(const std::string& path, const std::string& what, uint64_t hash = kFnvOffset);

/// A swing calibration fitted on the character's own physics (`amt animate`, fit_swing_on_motions), kept in the bind
/// cache beside the bind it was fitted on: `key` over everything the fit read besides the bind (the character file,
/// the calibration motions, the stretch limit and lead-in; the model's checkpoints are in the bind's key), the gain
/// (N_a) float, and the line the run reported. Stored as the archive's optional entries swing_fit_key, swing_fit_text
/// and swing_fit_gain, which its CRC-32 covers; empty (no key) when the file has none.
struct CachedSwingFit {
  std::string key, text;
  at::Tensor gain;
  bool empty() const { return key.empty(); }
};

/// The key of a bind: "fnv1a64:<16 hex>" over the mesh (V #V by 3, F #F by 3), rest joints (#J by 3),
/// the mask override (empty: none; else #V entries 0/1), the model's joint names and the contents of
/// its checkpoint files (bundle.dir/*.ckpt that the bundle loaded, apparel_own_weights.ckpt included), and the apparel
/// bones given as handles (null: none; their heads, parents and vertex weights), and the skin weights given in place
/// of the predicted ones (empty: none), and the bones whose physics response the module reads (`physics`: their vertex
/// weights and response). Throws amt::Error when a checkpoint file cannot be read.
std::string bind_key(const TriMesh& mesh, const MatrixX3f& joints, const std::vector<uint8_t>& mask_override,
                     const ModelBundle& bundle, const ApparelBones* bones = nullptr,
                     const MatrixXfR& weights = MatrixXfR(), const ApparelBones* physics = nullptr);

/// Writes a bound character and its key to `path` (through "<path>.amt-tmp"), with the swing fitted on it when `fit`
/// is not empty. Throws amt::Error when the file cannot be written.
void save_bind(const std::string& path, const std::string& key, const BoundCharacter& bound,
               const CachedSwingFit& fit = {});

/// Reads a bound character if `path` holds one with `key`. Returns false (and leaves `bound` alone)
/// when the file is missing, of another format or version, damaged, or made for another key;
/// `reason` then says which ("no file", "another mesh or model", ...). `fit`, when given, receives the swing fitted on
/// it (empty when the file holds none).
bool load_bind(const std::string& path, const std::string& key, BoundCharacter& bound, std::string* reason = nullptr,
               CachedSwingFit* fit = nullptr);

/// What bind_cached did.
struct BindResult {
  BoundCharacter bound;
  /// True when the cache file was used; `reason` says why it was not otherwise.
  bool cache_hit = false;
  std::string reason;
  /// The bind's key (bind_key; empty with the cache disabled) and, on a cache hit, the swing fitted on it that the
  /// file holds (empty when none).
  std::string key;
  CachedSwingFit swing_fit;
  /// Wall time of the bind or of reading the cache, seconds.
  double seconds = 0.0;
};

/// Loads the bind from `cache_path` when its key matches, else binds (bind_character with the mask
/// override, if any, `bones` as the apparel module's handles: BindOptions::apparel_bones, and `weights` in place of the
/// skinning predictor's: BindOptions::weights, `physics` as the bones whose response the apparel module reads:
/// BindOptions::physics_bones) and writes the cache. An empty `cache_path` disables the cache.
///   mesh (#V, #F), joints (#J by 3 on the bundle's skeleton), mask_override (empty or #V entries 0/1),
///   weights (empty, or #V by #J rows summing to 1: the character's own skin, canonical_file_weights)
BindResult bind_cached(const ModelBundle& bundle, const TriMesh& mesh, const MatrixX3f& joints,
                       const std::vector<uint8_t>& mask_override, const std::string& cache_path,
                       std::shared_ptr<const ApparelBones> bones = nullptr, const MatrixXfR& weights = MatrixXfR(),
                       std::shared_ptr<const ApparelBones> physics = nullptr);

}  // namespace amt
