#pragma once
// CRC-32 (zlib's: the polynomial of zip, PNG and gzip) of the payload of amt's own files.
// Checkpoints (models/checkpoint.h) and bind caches (infer/bind_cache_torch.h) store it beside their
// tensors and readers verify it, so that a flipped byte is an error, not a silently wrong model.
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace amt {

/// Continues `crc` (0 to start) over `size` bytes at `data`.
uint32_t crc32_update(uint32_t crc, const void* data, size_t size);

/// Continues `crc` over the length and the bytes of `text` (so that "ab", "c" and "a", "bc" differ).
uint32_t crc32_update(uint32_t crc, std::string_view text);

}  // namespace amt
