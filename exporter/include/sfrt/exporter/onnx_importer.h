// Imports a SceneEDNet-shaped ONNX graph (as torch.onnx.export writes it, opsets 11 to 17) into
// a ModelSpec. Supported: Conv, Pad (constant zero, folded into the next Conv), LeakyRelu, Relu
// (fused into the preceding Conv), Resize/Upsample (nearest, integer scale), Slice (as a crop),
// Identity, initialisers and Constant nodes; constant subgraphs over static shapes (Shape,
// Gather, Cast, Concat, Unsqueeze, ...) are evaluated at import. Any other node is an error that
// names the node, its op type and the supported set.
#pragma once

#include <string>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

enum class PaddingDetection {
  kAuto,       // SameUpper if every conv's pads equal the same-upper amounts at the traced size
  kSameUpper,  // force SameUpper (error if the traced pads contradict it)
  kExplicit,   // keep the traced numbers
};

struct OnnxImportOptions {
  PaddingDetection padding = PaddingDetection::kAuto;
};

// Fills layers, input (channels, traced size), output channels and producer (format, file
// name, SHA-256). Preprocessing and camera keep ModelSpec's defaults for the caller to set.
Result<ModelSpec> ImportOnnx(const std::string& path, const OnnxImportOptions& options = {});

}  // namespace sfrt::exporter
