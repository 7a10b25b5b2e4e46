// Serialises a ModelSpec into the .sfrt FlatBuffers format (runtime/schema/sfrt_model.fbs).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// The version recorded in Producer.exporter_version when the spec leaves it empty.
const char* ExporterVersion();

struct SerializeOptions {
  // Schema minor version to write (major is always kSchemaVersionMajor). kSchemaVersionMinor
  // (the default) writes Model.file_crc32c, the CRC-32C of the whole file, the 1.2 fields
  // (Model.training; OutputDesc.units as stated), the 1.3 ones (int8 convolutions, the
  // calibration record), 1.4's bf16 and 1.5's graphs (named inputs, Concat, Add, crops to a
  // second input); a chain of float32 layers has the tables of 1.2. 2 writes the 1.2 layout; 1
  // the 1.1 layout (the file CRC, a fixed units text, no training state); 0 the 1.0 layout, whose
  // only checksum covers the weights. Every 1.x runtime reads the layouts up to its own; 0 to 2
  // exist so tests can keep checking that this runtime still reads older files. Int8 layers and
  // a calibration record need 1.3, bf16 1.4, graphs 1.5, ConvTranspose2D and Pool2D 1.6, SameLower,
  // Resize and ChannelAffine 1.7, dilation, groups and the ChannelAffine-only activations 1.8.
  int schema_minor = kSchemaVersionMinor;
};

// Checks the spec (chain consistency, weight counts) and returns the file's bytes. Tensor data
// is 64-byte aligned relative to the start of the returned buffer.
Result<std::vector<uint8_t>> SerializeModel(const ModelSpec& spec,
                                            const SerializeOptions& options = {});

// Sets Model.file_crc32c of a serialised file (schema 1.1 or later) to the CRC-32C of all its
// bytes, the field's own 4 bytes taken as zero: the writer's last step, and what a tool or test
// that edits fields of a finished file calls afterwards. Fails, changing nothing, when the file's
// root table does not verify or has no file_crc32c field (a 1.0 file).
Status UpdateFileChecksum(std::span<uint8_t> file);

}  // namespace sfrt::exporter
