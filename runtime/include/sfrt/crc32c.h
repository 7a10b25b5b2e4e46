// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), the checksum of a model's weights.
// Software slicing-by-8; about 1-2 GB/s, so verifying an 85 MB model costs tens of milliseconds.
#pragma once

#include <cstddef>
#include <cstdint>

namespace sfrt {

// Extends `crc` (0 for a fresh checksum) over `size` bytes. Crc32c(Crc32c(0,a),b) == Crc32c(0,ab).
uint32_t Crc32c(uint32_t crc, const void* data, size_t size);

}  // namespace sfrt
