// Little/big-endian float32 conversion for the file formats in this directory.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>

namespace sfrt::io {

inline uint32_t ByteSwap32(uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0x0000ff00u) | ((v << 8) & 0x00ff0000u) | (v << 24);
}

// Reads `count` float32 values stored with the given byte order from `src` into `dst`.
inline void LoadFloats(const char* src, size_t count, bool little_endian, float* dst) {
  if (count == 0) return;  // memcpy must not see the null pointers of empty buffers
  const bool swap = little_endian != (std::endian::native == std::endian::little);
  if (!swap) {
    std::memcpy(dst, src, count * sizeof(float));
    return;
  }
  for (size_t i = 0; i < count; ++i) {
    uint32_t bits;
    std::memcpy(&bits, src + i * 4, 4);
    bits = ByteSwap32(bits);
    std::memcpy(dst + i, &bits, 4);
  }
}

// Stores `count` floats as little-endian float32 at `dst`.
inline void StoreFloatsLittleEndian(const float* src, size_t count, uint8_t* dst) {
  if (count == 0) return;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(dst, src, count * sizeof(float));
  } else {
    for (size_t i = 0; i < count; ++i) {
      uint32_t bits;
      std::memcpy(&bits, src + i, 4);
      bits = ByteSwap32(bits);
      std::memcpy(dst + i * 4, &bits, 4);
    }
  }
}

}  // namespace sfrt::io
