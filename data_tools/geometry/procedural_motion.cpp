#include "data_tools/geometry/procedural_motion.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "data_tools/geometry/error.h"

namespace amt {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kGravity = 9.8f;

Eigen::Quaternionf rot(float degrees, const Eigen::Vector3f& axis) {
  return Eigen::Quaternionf(Eigen::AngleAxisf(degrees * kPi / 180.0f, axis));
}

const Eigen::Vector3f kX = Eigen::Vector3f::UnitX(), kY = Eigen::Vector3f::UnitY(), kZ = Eigen::Vector3f::UnitZ();

void check_frames(const char* what, int frames, float fps) {
  AMT_CHECK(frames >= 1 && frames <= kMaxResampledFrames && std::isfinite(fps) && fps > 0 && fps <= 1000, what,
            ": expected frames in [1, ", kMaxResampledFrames, "] and fps in (0, 1000], found ", frames, " and ", fps);
}

void check_parameter(const char* what, const char* name, float value, float low, float high) {
  AMT_CHECK(std::isfinite(value) && value >= low && value <= high, what, ": expected ", name, " in [", low, ", ", high,
            "], found ", value);
}

// Legs, arms and pelvis of a walk cycle at `phase` (radians), the shape walk_motion has always had.
void pose_walk(Motion& m, int t, float phase) {
  const float swing = std::sin(phase);
  // Characters face +Z: a negative turn about +X swings a leg forward.
  m.rotation(t, kLeftHip) = rot(-25.0f * swing, kX);
  m.rotation(t, kRightHip) = rot(25.0f * swing, kX);
  m.rotation(t, kLeftKnee) = rot(35.0f * std::max(0.0f, std::sin(phase + 1.2f)), kX);
  m.rotation(t, kRightKnee) = rot(35.0f * std::max(0.0f, -std::sin(phase + 1.2f)), kX);
  m.rotation(t, kLeftAnkle) = rot(-10.0f * swing, kX);
  m.rotation(t, kRightAnkle) = rot(10.0f * swing, kX);
  // Arms down from the T-pose (about Z), then a swing about the vertical, opposite to the legs.
  m.rotation(t, kLeftShoulder) = rot(-20.0f * swing, kY) * rot(-70.0f, kZ);
  m.rotation(t, kRightShoulder) = rot(-20.0f * swing, kY) * rot(70.0f, kZ);
  m.rotation(t, kLeftElbow) = rot(-15.0f - 10.0f * swing, kY);
  m.rotation(t, kRightElbow) = rot(15.0f - 10.0f * swing, kY);
  m.rotation(t, kSpine2) = rot(4.0f * swing, kY);  // counter-rotation of the chest
  m.rotation(t, kPelvis) = rot(-4.0f * swing, kY);
}

// Uniform float in [low, high) from the top 24 bits of one engine output (platform independent).
float uniform(std::mt19937_64& rng, float low, float high) {
  const float u = static_cast<float>(rng() >> 40) * (1.0f / 16777216.0f);
  return low + (high - low) * u;
}

// +1 or -1 from one engine output.
float random_sign(std::mt19937_64& rng) {
  return (rng() >> 63) ? 1.0f : -1.0f;
}

}  // namespace

// === Motions with parameters

Motion walk_motion(int frames, float fps, float speed, float stride_seconds) {
  check_frames("walk_motion", frames, fps);
  check_parameter("walk_motion", "stride_seconds", stride_seconds, 0.05f, 100.0f);
  check_parameter("walk_motion", "speed", speed, -100.0f, 100.0f);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  for (int t = 0; t < frames; ++t) {
    const float phase = 2.0f * kPi * (t / fps) / stride_seconds;
    pose_walk(m, t, phase);
    m.root_translation.row(t) << 0.0f, 0.02f * std::cos(2.0f * phase) - 0.02f, speed * t / fps;
  }
  return m;
}

Motion run_motion(int frames, float fps, float speed, float stride_seconds) {
  check_frames("run_motion", frames, fps);
  check_parameter("run_motion", "stride_seconds", stride_seconds, 0.05f, 100.0f);
  check_parameter("run_motion", "speed", speed, -100.0f, 100.0f);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  for (int t = 0; t < frames; ++t) {
    const float phase = 2.0f * kPi * (t / fps) / stride_seconds;
    const float swing = std::sin(phase);
    m.rotation(t, kLeftHip) = rot(-10.0f - 35.0f * swing, kX);
    m.rotation(t, kRightHip) = rot(-10.0f + 35.0f * swing, kX);
    m.rotation(t, kLeftKnee) = rot(20.0f + 70.0f * std::max(0.0f, std::sin(phase + 1.4f)), kX);
    m.rotation(t, kRightKnee) = rot(20.0f + 70.0f * std::max(0.0f, -std::sin(phase + 1.4f)), kX);
    m.rotation(t, kLeftAnkle) = rot(-15.0f * swing, kX);
    m.rotation(t, kRightAnkle) = rot(15.0f * swing, kX);
    // Bent arms pumping forward and back, opposite to the legs.
    m.rotation(t, kLeftShoulder) = rot(-35.0f * swing, kY) * rot(-65.0f, kZ);
    m.rotation(t, kRightShoulder) = rot(-35.0f * swing, kY) * rot(65.0f, kZ);
    m.rotation(t, kLeftElbow) = rot(-80.0f - 10.0f * swing, kY);
    m.rotation(t, kRightElbow) = rot(80.0f - 10.0f * swing, kY);
    m.rotation(t, kSpine1) = rot(10.0f, kX);  // forward lean
    m.rotation(t, kSpine2) = rot(8.0f * swing, kY);
    m.rotation(t, kPelvis) = rot(-8.0f * swing, kY);
    // Two flight phases per stride: the pelvis is highest between the steps.
    m.root_translation.row(t) << 0.0f, 0.04f * std::abs(std::cos(phase)) - 0.06f, speed * t / fps;
  }
  return m;
}

Motion turn_motion(int frames, float fps, float turn_degrees_per_second, float speed) {
  check_frames("turn_motion", frames, fps);
  check_parameter("turn_motion", "turn_degrees_per_second", turn_degrees_per_second, -1000.0f, 1000.0f);
  check_parameter("turn_motion", "speed", speed, -100.0f, 100.0f);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  const float omega = turn_degrees_per_second * kPi / 180.0f;  // rad/s
  const float stride_seconds = 1.1f;
  for (int t = 0; t < frames; ++t) {
    const float time = t / fps;
    const float phase = 2.0f * kPi * time / stride_seconds;
    pose_walk(m, t, phase);
    const float heading = omega * time;  // about +Y: +Z turns towards +X, the character's left
    m.rotation(t, kPelvis) = Eigen::Quaternionf(Eigen::AngleAxisf(heading, kY)) * m.rotation(t, kPelvis);
    // Position on the arc: the integral of speed * (sin heading, 0, cos heading).
    float x = 0.0f, z = speed * time;
    if (std::abs(omega) > 1e-6f) {
      x = speed / omega * (1.0f - std::cos(heading));
      z = speed / omega * std::sin(heading);
    }
    m.root_translation.row(t) << x, 0.02f * std::cos(2.0f * phase) - 0.02f, z;
  }
  return m;
}

Motion jump_motion(int frames, float fps, float height, float period_seconds) {
  check_frames("jump_motion", frames, fps);
  check_parameter("jump_motion", "height", height, 0.0f, 2.0f);
  const float flight = 2.0f * std::sqrt(2.0f * height / kGravity);
  AMT_CHECK(std::isfinite(period_seconds) && period_seconds > flight + 0.5f && period_seconds <= 100.0f,
            "jump_motion: expected period_seconds in (", flight + 0.5f, ", 100] for a jump of ", height,
            " m, found ", period_seconds);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  const float prepare = 0.5f * (period_seconds - flight);  // crouch before take-off; the landing takes the rest
  const float land = period_seconds - prepare - flight;
  const float v0 = 0.5f * kGravity * flight;  // take-off speed
  for (int t = 0; t < frames; ++t) {
    const float u = std::fmod(t / fps, period_seconds);
    float crouch = 0.0f, y = 0.0f, arms = 0.0f;  // crouch depth (m), root height (m), arm raise in [0, 1]
    if (u < prepare) {
      crouch = 0.12f * std::sin(kPi * u / prepare);
      arms = -0.3f * std::sin(kPi * u / prepare);  // arms swing back in the crouch
    } else if (u < prepare + flight) {
      const float s = u - prepare;
      y = v0 * s - 0.5f * kGravity * s * s;
      arms = std::sin(kPi * s / flight);
    } else {
      crouch = 0.12f * std::sin(kPi * (u - prepare - flight) / land);
    }
    const float bend = crouch / 0.12f;  // 0..1
    m.rotation(t, kLeftHip) = rot(-45.0f * bend - 10.0f * arms, kX);
    m.rotation(t, kRightHip) = rot(-45.0f * bend - 10.0f * arms, kX);
    m.rotation(t, kLeftKnee) = rot(80.0f * bend + 15.0f * std::max(0.0f, arms), kX);
    m.rotation(t, kRightKnee) = rot(80.0f * bend + 15.0f * std::max(0.0f, arms), kX);
    m.rotation(t, kLeftAnkle) = rot(-35.0f * bend, kX);
    m.rotation(t, kRightAnkle) = rot(-35.0f * bend, kX);
    m.rotation(t, kSpine1) = rot(25.0f * bend, kX);
    // Arms from down (70 degrees below the horizontal) up towards overhead in the flight.
    m.rotation(t, kLeftShoulder) = rot(-70.0f + 110.0f * arms, kZ);
    m.rotation(t, kRightShoulder) = rot(70.0f - 110.0f * arms, kZ);
    m.root_translation.row(t) << 0.0f, y - crouch, 0.0f;
  }
  return m;
}

Motion spin_motion(int frames, float fps, float turns_per_second) {
  check_frames("spin_motion", frames, fps);
  check_parameter("spin_motion", "turns_per_second", turns_per_second, -5.0f, 5.0f);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  const float omega = 2.0f * kPi * turns_per_second;
  const float ramp = 0.5f;  // seconds to full speed
  for (int t = 0; t < frames; ++t) {
    const float time = t / fps;
    const float angle = time < ramp ? omega * time * time / (2.0f * ramp) : omega * (time - 0.5f * ramp);
    const float bounce = 0.5f - 0.5f * std::cos(4.0f * kPi * time);
    m.rotation(t, kPelvis) = Eigen::Quaternionf(Eigen::AngleAxisf(angle, kY));
    m.rotation(t, kLeftHip) = rot(-8.0f * bounce, kX);
    m.rotation(t, kRightHip) = rot(-8.0f * bounce, kX);
    m.rotation(t, kLeftKnee) = rot(15.0f * bounce, kX);
    m.rotation(t, kRightKnee) = rot(15.0f * bounce, kX);
    m.rotation(t, kLeftShoulder) = rot(-20.0f, kZ);  // arms out, a little below the horizontal
    m.rotation(t, kRightShoulder) = rot(20.0f, kZ);
    m.rotation(t, kLeftElbow) = rot(-10.0f, kY);
    m.rotation(t, kRightElbow) = rot(10.0f, kY);
    m.rotation(t, kHead) = rot(10.0f * std::sin(2.0f * kPi * time), kX);
    m.root_translation.row(t) << 0.0f, -0.03f * bounce, 0.0f;
  }
  return m;
}

Motion dance_motion(int frames, float fps, float beats_per_minute, float energy) {
  check_frames("dance_motion", frames, fps);
  check_parameter("dance_motion", "beats_per_minute", beats_per_minute, 20.0f, 300.0f);
  check_parameter("dance_motion", "energy", energy, 0.0f, 2.0f);
  Motion m = rest_motion(canonical_skeleton(), frames, fps);
  const float e = energy;
  for (int t = 0; t < frames; ++t) {
    const float beat = 2.0f * kPi * (beats_per_minute / 60.0f) * (t / fps);  // one period per beat
    const float bounce = 0.5f - 0.5f * std::cos(beat);                         // knees on every beat
    const float sway = std::sin(0.5f * beat);                                   // hips every two beats
    const float wave = 0.5f + 0.5f * std::sin(0.25f * beat);                    // arms every four beats
    m.rotation(t, kPelvis) = rot(6.0f * e * sway, kZ) * rot(8.0f * e * std::sin(0.5f * beat + 0.8f), kY);
    m.rotation(t, kSpine2) = rot(-10.0f * e * std::sin(0.5f * beat + 0.8f), kY);
    m.rotation(t, kSpine3) = rot(-4.0f * e * sway, kZ);
    m.rotation(t, kLeftHip) = rot(-12.0f * e * bounce, kX) * rot(-6.0f * e * sway, kZ);
    m.rotation(t, kRightHip) = rot(-12.0f * e * bounce, kX) * rot(-6.0f * e * sway, kZ);
    m.rotation(t, kLeftKnee) = rot(22.0f * e * bounce, kX);
    m.rotation(t, kRightKnee) = rot(22.0f * e * bounce, kX);
    // Arms alternate between down at the sides and raised above the shoulders, waving forward and back.
    m.rotation(t, kLeftShoulder) = rot(-25.0f * e * std::sin(0.5f * beat), kY) * rot(-70.0f + 50.0f * e * wave, kZ);
    m.rotation(t, kRightShoulder) =
        rot(-25.0f * e * std::sin(0.5f * beat + kPi), kY) * rot(70.0f - 50.0f * e * (1.0f - wave), kZ);
    m.rotation(t, kLeftElbow) = rot(-20.0f - 30.0f * e * (0.5f + 0.5f * std::sin(beat)), kY);
    m.rotation(t, kRightElbow) = rot(20.0f + 30.0f * e * (0.5f + 0.5f * std::sin(beat + kPi)), kY);
    m.rotation(t, kHead) = rot(6.0f * e * std::sin(beat), kX);
    m.root_translation.row(t) << 0.06f * e * sway, -0.04f * e * bounce, 0.0f;
  }
  return m;
}

// === Seeded variations

const char* procedural_kind_name(ProceduralKind kind) {
  switch (kind) {
    case ProceduralKind::kWalk: return "walk";
    case ProceduralKind::kRun: return "run";
    case ProceduralKind::kTurn: return "turn";
    case ProceduralKind::kJump: return "jump";
    case ProceduralKind::kSpin: return "spin";
    case ProceduralKind::kDance: return "dance";
  }
  return "unknown";
}

Motion random_procedural_motion(ProceduralKind kind, uint64_t seed, int frames, float fps) {
  std::mt19937_64 rng(seed);
  switch (kind) {
    case ProceduralKind::kWalk: {
      const float speed = uniform(rng, 0.8f, 1.6f);
      return walk_motion(frames, fps, speed, uniform(rng, 0.9f, 1.3f));
    }
    case ProceduralKind::kRun: {
      const float speed = uniform(rng, 2.2f, 4.0f);
      return run_motion(frames, fps, speed, uniform(rng, 0.6f, 0.8f));
    }
    case ProceduralKind::kTurn: {
      const float rate = random_sign(rng) * uniform(rng, 30.0f, 90.0f);
      return turn_motion(frames, fps, rate, uniform(rng, 0.6f, 1.4f));
    }
    case ProceduralKind::kJump: {
      const float height = uniform(rng, 0.15f, 0.45f);
      return jump_motion(frames, fps, height, uniform(rng, 1.5f, 2.0f));
    }
    case ProceduralKind::kSpin: {
      const float turns = random_sign(rng) * uniform(rng, 0.4f, 1.2f);
      return spin_motion(frames, fps, turns);
    }
    case ProceduralKind::kDance: {
      const float bpm = uniform(rng, 90.0f, 140.0f);
      return dance_motion(frames, fps, bpm, uniform(rng, 0.6f, 1.4f));
    }
  }
  fail("random_procedural_motion: unknown kind ", static_cast<int>(kind));
}

}  // namespace amt
