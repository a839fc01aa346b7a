#pragma once
// The canonical 22-joint skeleton of a file's skeleton (docs/architecture.md, "The data model"): the joints that the name tables and the
// structure map (data_tools/formats/joint_map.h), the canonical joints the file lacks placed between their mapped
// neighbours, and for every file joint the canonical joint that carries it. Shared by the runtime's characters
// (infer/character_input.h) and the dataset builder's PMX characters (data_tools/builder/pmx_dataset.h). Real
// skeletons are not canonical (issue 6, item 3): a canonical joint that the file lacks (no collars, two spine
// joints instead of three, no foot) is placed on the line between its mapped neighbours; the file's extra joints
// (twist, finger, apparel bones) are carried along by their nearest mapped ancestor.
#include <optional>
#include <string>
#include <vector>

#include "data_tools/formats/joint_map.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

// === Canonical rest skeleton of a file skeleton

/// The canonical skeleton of a file skeleton and how it was made.
///   skeleton        canonical names and parents; rest joints from the mapped file joints (metres)
///   mapping         the file joint of each canonical joint (data_tools/formats/joint_map.h)
///   placed          canonical joints the file lacks (their file joint is their canonical parent's),
///                   placed evenly on the line between the nearest mapped ancestor and descendant
///                   (a leaf, the foot, continues its parent bone in the canonical proportions)
///   carrier         per file joint, the canonical joint that carries it: its own when it is mapped,
///                   else that of its nearest mapped ancestor (the pelvis for joints above the root)
///   extra           names of the file joints that no canonical joint maps (carried by `carrier`)
struct CanonicalRest {
  Skeleton skeleton;
  JointMapping mapping;
  std::vector<int> placed;
  std::vector<int> carrier;
  std::vector<std::string> extra;

  /// Several lines: the canonical joint <- file joint table with how each was found, the placed
  /// joints and the extra joints.
  std::string describe(const std::vector<std::string>& file_names) const;
};

/// Places the canonical joints that share their file joint with their canonical parent (the file lacks
/// them): a chain of such joints is spread evenly on the line from its mapped ancestor to its first
/// mapped descendant (along first children in canonical order); a chain without one (a foot on its
/// ankle) continues the canonical skeleton's bones, scaled like the parent bone.
///   rest_joints  #22 by 3 canonical rest joints, each at its mapped file joint; updated in place
/// Returns the placed canonical joints, ascending.
std::vector<int> place_missing_joints(MatrixX3f& rest_joints, const JointMapping& mapping);

/// Maps a file skeleton onto the canonical joints (map_to_canonical) and places the missing ones.
/// `file` need not be topological (parents -1 for roots, no cycles); `source` names it in errors.
/// Throws amt::Error when the joints cannot be mapped (the message lists the file's joints and
/// suggests --character-joint-map).
CanonicalRest canonical_rest(const Skeleton& file, const std::optional<JointMapFile>& user_map,
                             const std::string& source);

}  // namespace amt
