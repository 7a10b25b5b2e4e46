// Atomic file replacement for the tool's outputs.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "sfrt/status.h"

namespace sfrt::tools {

// Writes `bytes` to `path` atomically: the data goes to a temporary file in the same directory,
// which is flushed to disk (fsync) and then renamed over `path`. On any failure the temporary file
// is removed and `path` is left as it was. Errors name the file and the failing step.
Status WriteFileAtomically(const std::string& path, std::span<const uint8_t> bytes);

// Reads a whole file. Errors name the file.
Result<std::string> ReadWholeFile(const std::string& path);

}  // namespace sfrt::tools
