#pragma once
// `amt dataset artist-style`: a dataset shard's characters remade as artists build models (artist_style.h), with
// their clips' ground truth remade with them, written as a new shard that every amt command reads: to animate,
// picture, view or train on the remakes that `amt eval --artist-style` scores on the fly.
#include <cstdint>
#include <string>

#include "data_tools/builder/artist_style.h"

namespace amt {

/// What write_artist_style_dataset remakes.
///   remake     how each character is remade (the same options as `amt eval --artist-style --artist-style-seed
///              --artist-style-vertices` give the same remake that evaluation scores)
///   character  only this character (empty: every character of the file)
///   max_clips  at most this many clips per character, the first in file order (0: all)
///   progress   print a progress line per clip on stderr
struct ArtistStyleDatasetOptions {
  ArtistStyleOptions remake;
  std::string character;
  int max_clips = 0;
  bool progress = true;
};

/// What was written.
struct ArtistStyleDatasetSummary {
  int characters = 0, clips = 0;
  int64_t frames = 0, vertices = 0;
};

/// Reads the shard `in`, remakes its characters (artist_style_character) and their clips' ground truth
/// (remake_frames, as vertices), and writes them to `out` (a temporary name, then renamed) under the same names,
/// splits and frame rate. Throws amt::Error on a missing or unreadable shard, an unknown `character`, a character
/// the remake cannot take (naming it), or an `out` that is the same file as `in`.
ArtistStyleDatasetSummary write_artist_style_dataset(const std::string& in, const std::string& out,
                                                     const ArtistStyleDatasetOptions& options = {});

}  // namespace amt
