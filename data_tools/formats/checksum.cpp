#include "data_tools/formats/checksum.h"

#include <zlib.h>

#include <algorithm>
#include <limits>

namespace amt {

uint32_t crc32_update(uint32_t crc, const void* data, size_t size) {
  const auto* bytes = static_cast<const Bytef*>(data);
  uLong value = crc;
  while (size > 0) {  // zlib takes at most a uInt of bytes per call
    const uInt n = uInt(std::min<size_t>(size, std::numeric_limits<uInt>::max()));
    value = ::crc32(value, bytes, n);
    bytes += n, size -= n;
  }
  return uint32_t(value);
}

uint32_t crc32_update(uint32_t crc, std::string_view text) {
  const uint64_t length = text.size();
  crc = crc32_update(crc, &length, sizeof(length));
  return crc32_update(crc, text.data(), text.size());
}

}  // namespace amt
