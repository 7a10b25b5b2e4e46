// SHA-256 (FIPS 180-4): which source file a model came from (the exporter), which model and
// work list a shard of a fleet replay ran (sfrt eval --shard, sfrt merge).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "sfrt/status.h"

namespace sfrt {

class Sha256 {
 public:
  Sha256();
  void Update(const void* data, size_t size);
  std::string FinishHex();  // lowercase hex; the object is spent afterwards

 private:
  void Compress(const uint8_t block[64]);
  uint32_t state_[8];
  uint8_t buffer_[64];
  size_t buffered_ = 0;
  uint64_t total_bytes_ = 0;
};

// SHA-256 of a whole file, lowercase hex. Errors name the file.
Result<std::string> Sha256OfFile(const std::string& path);

}  // namespace sfrt
