#pragma once
// Procedural motions on the canonical skeleton: variety that does not depend on mocap files.
#include "data_tools/motion.h"

namespace amt {

/// A walk cycle on the canonical skeleton: legs swing about the hips with knee bend, arms lowered
/// from the T-pose swing opposite to the legs, the pelvis bobs, and the root travels along +Z at
/// `speed` m/s with one stride every `stride_seconds`. Starts mid-stride at frame 0.
Motion walk_motion(int frames, float fps = 30.0f, float speed = 1.2f, float stride_seconds = 1.1f);

}  // namespace amt
