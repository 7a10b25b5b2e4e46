// NumPy .npy files holding float32 arrays (the format of numpy.save).
//
// Supported: format versions 1.0 and 2.0, dtype '<f4' (little-endian float32), C order
// (fortran_order False), any number of dimensions. Everything else is rejected with a message
// that names the file and the header field at fault.
// Byte layout: "\x93NUMPY", major, minor, header length (uint16 LE for 1.0, uint32 LE for 2.0),
// an ASCII Python dict literal {'descr': '<f4', 'fortran_order': False, 'shape': (H, W, C), }
// padded with spaces and a final '\n' so the data starts at a multiple of 64 bytes, then the data.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::io {

struct NpyArray {
  std::vector<int64_t> shape;  // empty for a 0-d array (one element)
  std::vector<float> data;     // C order, product(shape) elements

  size_t element_count() const;
  // "(3, 4)" as NumPy prints shapes; "()" for 0-d.
  std::string ShapeString() const;
};

// Reads a .npy file. Errors name the file and, for header problems, the field.
Result<NpyArray> ReadNpy(const std::string& path);

// Parses .npy bytes held in memory; `label` names them in error messages.
Result<NpyArray> ParseNpy(std::string_view bytes, const std::string& label);

// Serialises a float32 array as .npy bytes (version 1.0, or 2.0 if the header needs it).
// Fails if data.size() does not equal the product of `shape` or a dimension is negative.
Result<std::vector<uint8_t>> SerializeNpy(std::span<const int64_t> shape,
                                          std::span<const float> data);

// SerializeNpy, then writes `path` atomically (temporary file + rename).
Status WriteNpy(const std::string& path, std::span<const int64_t> shape,
                std::span<const float> data);

}  // namespace sfrt::io
