#pragma once
// The topology amt derives from an artist's mesh, and the handles that move its apparel.
//
// Artists' models split vertices at every UV seam (two coincident vertices that must move as one) and
// build hair, skirts and capes from many separate, overlapping, double-sided strips and panels. Every
// graph amt builds on a mesh (the apparel graph, attachment paths, connected parts, geodesics) is built
// on the **linked** edge set: the mesh's own edges, plus a zero-length seam link from every vertex to
// the vertex it welds to, plus proximity links between separate apparel pieces that lie within a few
// millimetres of each other at rest (a bundle of hair strips, the two sides of a double-sided panel,
// layered skirt panels). The existing graph algorithms then see one piece where the artist made many.
//
// Apparel on handles: each apparel piece moves through a small set of handles, apparel vertices picked
// along the distance from where the piece hangs (so they form chains down a strand and rings round a
// skirt), with smooth weights from handles to vertices over the linked graph, shared by every strip
// that lies with them. A handle's motion is the learned module's output; a vertex follows by
// interpolating its handles' offsets from where rigid skinning carries them, so it cannot tear.
// Hand-written: no Debian library builds such rigs (the graph searches are a few bounded Dijkstras).
#include <cstdint>
#include <string>
#include <vector>

#include "data_tools/geometry/rig_probe.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === Linked topology

/// Choices of linked_topology.
///   weld_tolerance     vertices nearer than this (metres) are one point (weld_vertices)
///   proximity_radius   apparel vertices of different welded parts nearer than this (metres) are linked
///                      (0: no proximity links)
///   proximity_links    at most this many proximity links from each vertex (to its nearest vertices in
///                      other parts, one per part)
struct TopologyOptions {
  float weld_tolerance = 1e-3f;
  float proximity_radius = 4e-3f;
  int proximity_links = 2;
};

/// What linked_topology found.
///   edges            #E by 2 unique edges (i < j): the mesh's, seam links, proximity links
///   weld             #V: the smallest index of the vertices each vertex welds to (weld_vertices)
///   seam_links       links from a vertex to a coincident copy (zero or tiny length)
///   proximity_links  links between separate apparel pieces
///   refused_links    coincident pairs left apart because the mask calls one body and the other apparel
///   parts, welded_parts, linked_parts   connected parts of the mesh's edges, with seam links, and with
///                    every link
struct LinkedTopology {
  MatrixX2i edges;
  std::vector<int32_t> weld;
  int seam_links = 0, proximity_links = 0, refused_links = 0;
  int parts = 0, welded_parts = 0, linked_parts = 0;
};

/// The linked edge set of (V, F). `apparel_mask` (#V entries 0/1, or empty: everything is apparel for
/// the proximity links and no weld is refused) says which vertices the proximity links join; a weld
/// between a body and an apparel vertex is refused and counted (the mask decides which side each copy
/// moves with), and the copies on each side of a group that straddles them are linked to the smallest of
/// them on that side (canonical_copies). Deterministic. Throws amt::Error on options out of range or a mask of another
/// length.
LinkedTopology linked_topology(const MatrixX3f& V, const MatrixX3i& F, const std::vector<uint8_t>& apparel_mask,
                               const TopologyOptions& options = {});

/// The mask made the same on every weld group (weld from linked_topology or weld_vertices): a copy takes
/// its group's smallest vertex's value, so that a seam never straddles body and apparel. Returns how many
/// entries changed in `changed` when given.
std::vector<uint8_t> weld_consistent_mask(const std::vector<uint8_t>& mask, const std::vector<int32_t>& weld,
                                          int* changed = nullptr);

/// Each vertex's canonical copy: the smallest vertex of its weld group (weld, from linked_topology) on the same
/// side of the mask. A group that straddles body and apparel (a refused weld) splits in two, each side one point.
std::vector<int32_t> canonical_copies(const std::vector<int32_t>& weld, const std::vector<uint8_t>& mask);

/// Geodesic distances (ids.size(), J) of the vertices `ids` (ascending) over the sub-mesh of those vertices
/// as geodesic_distances computes them, on the mesh welded by `canon` (canonical_copies): every face corner
/// is replaced by its canonical copy, the distances are computed for the canonical vertices among ids, and
/// each copy takes its canonical vertex's row, so coincident copies get the same distances (a UV seam is
/// no cut). Throws amt::Error naming `what` when the sub-mesh has no faces or a copy's canonical vertex is
/// not among ids.
MatrixXfR welded_geodesics(const MatrixX3f& V, const MatrixX3i& F, const MatrixX3f& joints,
                           const std::vector<int32_t>& ids, const std::vector<int32_t>& canon, const std::string& what);

// === Handles

/// Choices of apparel_handles.
///   spacing     handles are at least this far apart along the linked apparel graph (metres, > 0)
///   radius      a vertex is moved by the handles within this graph distance (metres, > spacing)
///   max_handles per vertex, the nearest (>= 1)
struct HandleOptions {
  float spacing = 0.04f;
  float radius = 0.09f;
  int max_handles = 4;
};

/// A rig of handles over the apparel vertices (positions in the caller's apparel list).
///   handles          H positions in the apparel list, in the order they were picked (nearest to where
///                    the piece hangs first)
///   vertex_handles   N_a by max_handles handle indices (0..H-1), nearest first, padded with the first
///   vertex_weights   N_a by max_handles weights, rows sum to 1, padding 0
///   handle_edges     #E by 2 pairs of handle indices (i < j): handles whose regions overlap (a vertex
///                    weighted by both, or one within radius of the other)
struct ApparelHandles {
  std::vector<int32_t> handles;
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> vertex_handles;
  MatrixXfR vertex_weights;
  MatrixX2i handle_edges;
  int num_handles() const { return static_cast<int>(handles.size()); }
};

/// Handles of the apparel vertices `apparel` (ascending mesh indices) of V, over the edges `edges` (mesh
/// indices; the linked edges) between apparel vertices, picked greedily in order of `hang_distance`
/// (N_a entries, each vertex's distance along the apparel from where its piece hangs; ties by position):
/// a vertex becomes a handle when no handle is within `spacing` of it along the graph. A vertex's weights
/// are (1 - (d / radius)^2)^2 of its graph distance d to each handle within radius, the nearest
/// max_handles kept and normalised; a vertex that no handle reaches within radius (none: every vertex is
/// within spacing of one) would take its nearest. Deterministic. Throws amt::Error on options out of
/// range or inputs of the wrong size.
ApparelHandles apparel_handles(const MatrixX3f& V, const MatrixX2i& edges, const std::vector<int32_t>& apparel,
                               const std::vector<float>& hang_distance, const HandleOptions& options = {});

// === The rig's own bones as handles

/// A character's own apparel bones, the bones its artist (or the builder's simulation) moves the apparel with:
/// a PMX model's physics-driven bones, a glTF's chains outside the canonical skeleton, a dataset rig's bones
/// that are not joints of its skeleton.
///   names     B bone names
///   heads     (B, 3) rest positions of the bones, metres, in the mesh's frame
///   parents   B parent indices among these bones, -1 for a chain's first bone
///   indices, weights  (N, K) per mesh vertex: bone indices among these bones (-1: none) and the vertex's own
///             skin weights on them (not renormalised: a vertex half on a body bone has 0.5 here)
///   response  (B, kRigResponseChannels) how each bone responds to the body's motion under the character's own
///             physics (rig_response, data_tools/builder/rig_response.h), or empty when unknown
struct ApparelBones {
  std::vector<std::string> names;
  MatrixX3f heads;
  std::vector<int32_t> parents;
  Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> indices;
  MatrixXfR weights;
  MatrixXfR response;
  int num_bones() const { return static_cast<int>(names.size()); }
};

/// The bones `keep` (B_all entries, 1 = apparel bone) of a rig of B_all bones (names, rest heads (B_all, 3), parents
/// in [-1, B_all)), with per-vertex influences (N, K) over all of them: the kept bones renumbered, parents mapped to
/// the nearest kept ancestor, influences on other bones dropped; `response` (B_all rows, or empty) keeps the kept
/// bones' rows. Throws amt::Error on inputs of the wrong size.
ApparelBones select_apparel_bones(
    const std::vector<std::string>& names, const MatrixX3f& heads, const std::vector<int32_t>& parents,
    const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices, const MatrixXfR& weights,
    const std::vector<uint8_t>& keep, const MatrixXfR& response = MatrixXfR());

/// The response of each vertex `vertices` (ascending or not; M entries) from its bones': channel 0 the share of its
/// skin weight on bones the simulation moves, channels 1.. the weighted mean of those bones' responses (0 where it
/// has none). indices (N, K) bone indices (< 0 or >= B: none), weights (N, K), bone_response (B,
/// kRigResponseChannels) -> (M, kRigResponseChannels). Throws amt::Error on inputs of the wrong size.
MatrixXfR vertex_response(const Eigen::Matrix<int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& indices,
                          const MatrixXfR& weights, const MatrixXfR& bone_response,
                          const std::vector<int32_t>& vertices);

/// Handles of the apparel vertices `apparel` (ascending mesh indices) of V from the character's own bones: one
/// handle per bone that weighs an apparel vertex, at the apparel vertex it weighs most (ties: the one nearest its
/// head; a vertex already another bone's handle is skipped, and a bone left without one joins the handle of the
/// vertex it weighs most). A vertex's weights are its own skin weights on the handles' bones, the heaviest
/// `max_handles` kept and normalised; a vertex weighted by no apparel bone (a mask wider than the rig) takes the
/// handle nearest to it at rest. Edges: handles that share a vertex, and each bone's handle with its nearest
/// ancestor's. Handles are listed in bone order. Deterministic. Throws amt::Error on inputs of the wrong size or
/// max_handles < 1, and when no apparel vertex is weighted by any bone (naming the count).
ApparelHandles bone_handles(const MatrixX3f& V, const std::vector<int32_t>& apparel, const ApparelBones& bones,
                            int max_handles = 4);

}  // namespace amt
