#pragma once
// CRC-32 of tensors (data_tools/formats/checksum.h): their shape and the bytes of their elements.
#include <ATen/ATen.h>

#include <cstdint>

#include "data_tools/formats/checksum.h"

namespace amt {

/// Continues `crc` over the sizes and the element bytes of `t` (any dtype, on the CPU).
inline uint32_t crc32_update(uint32_t crc, const at::Tensor& t) {
  const at::Tensor c = t.contiguous();
  for (const int64_t size : c.sizes()) crc = crc32_update(crc, &size, sizeof(size));
  return crc32_update(crc, c.data_ptr(), size_t(c.nbytes()));
}

}  // namespace amt
