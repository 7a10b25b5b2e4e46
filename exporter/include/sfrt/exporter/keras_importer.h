// Imports a SceneEDNet-shaped Keras 2 model saved as HDF5 into a ModelSpec, with the HDF5 C
// library and nlohmann-json.
//
// Files read (Keras 2.1 to 2.x, TensorFlow backend, as `model.save()` / `save_weights()` write
// them):
//   full model    root attribute `model_config` (JSON text, fixed- or variable-length string),
//                 weights in group `model_weights`: attribute `layer_names`, one group per
//                 layer with attribute `weight_names`, datasets at `<layer>/<weight name>`
//                 (e.g. `model_weights/conv0/conv0/kernel:0`). `keras_version`, `backend` and
//                 `training_config` are read for messages or ignored.
//   weights only  the same layer groups and `layer_names` at the root; the architecture comes
//                 from KerasImportOptions::architecture_json (the text of `model.to_json()`).
//                 Given for a full-model file, the architecture file replaces `model_config`.
// Architectures: functional `Model` (class_name "Model" or "Functional") and `Sequential`
// (config as a list, Keras <= 2.2.2, or {"layers": [...]}). The layers from the input to the
// single output form a chain, or (functional) a graph with skip connections (schema 1.5), of:
//   InputLayer     batch_input_shape (None, H, W, C); H/W may be None (traced size unknown)
//   Conv2D         channels_last, dilation 1, any kernel and strides, padding 'same' (stored as
//                  PaddingRule::kSameUpper: TensorFlow pads the excess at the bottom/right) or
//                  'valid' (explicit, plus any ZeroPadding2D right before it), use_bias,
//                  activation 'linear' or 'relu'. Kernels (kh, kw, in, out) are HWIO as stored.
//   BatchNormalization  inference (moving statistics), channels axis; folded into the Conv2D
//                  (activation 'linear') right before it
//   LeakyReLU      `alpha` (required), fused into the Conv2D (or Add) right before it
//   Activation     'linear' (dropped) or 'relu' (fused into the Conv2D right before it)
//   UpSampling2D   integer size, interpolation 'nearest'
//   Cropping2D     ((top, bottom), (left, right)); see "Crop rule"
//   ZeroPadding2D  folded into the next Conv2D, which must use padding 'valid'
//   Concatenate    axis -1 (channels) of tensors of equal height and width
//   Add            of two tensors of the same shape
// BatchNormalization and activations fold into the layer before them only where no other layer
// reads that layer's output. A Cropping2D whose only reader is a Concatenate that also reads an
// earlier tensor of the crop's built size becomes CropRule::kToSecondInput (a U-Net cutting an
// upsampled tensor to its skip's size; an axis with nothing removed takes the other axis' side,
// or bottom/right).
// Anything else is an error naming the layer, its class and this set.
//
// multi_gpu_model checkpoints: when the saved model is a wrapper (InputLayer, Lambda and
// Concatenate layers around exactly one nested Model/Sequential layer), the nested model is
// exported with the weights of its group; the wrapper's batch split/merge is a training device
// placement, not part of the network. KerasImportResult::notes says so.
//
// Weights: a top-level layer's weights are the datasets its group lists in `weight_names`, in
// that order (Conv2D: kernel, then bias if use_bias). A nested model's group lists all its
// layers' weights; they are assigned in layer order, as Keras loads them. Datasets may be any
// floating-point type (float16/32/64); they are converted to float32.
//
// Crop rule: Keras states a crop's amounts for the size the model was built at. A Cropping2D
// becomes CropRule::kToInputSize when the built size is known, the crop's output has the
// model input's height and width there, and on each axis it removes rows (columns) from at most
// one side: the authors' ((4, 0), (0, 0)) at 540x960 removes 16*ceil(H/16)-H rows from the top
// at every size. The excess goes from the side the crop removed it from (top/left when it
// removed nothing on that axis). It stays CropRule::kExplicit (the same amounts at every size)
// when the built size is unknown (InputLayer H/W None), when its output differs from the input
// size at the built size, or when it crops both sides of an axis; a note says so.
//
// Errors are one line: "<file>: layer '<name>' (<class>): <what>", naming the dataset, group or
// attribute at fault.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// Where a bilinear UpSampling2D samples its input. TensorFlow 2 (tf.keras of Keras 2.4 and
// later, Keras 3) resizes on the half-pixel grid, source = (y + 0.5) / factor - 0.5; TensorFlow 1
// (tf.keras and Keras 2.0-2.3 on it) on the asymmetric one, source = y / factor
// (align_corners=False without half-pixel centres). Both clamp to the edge.
enum class KerasBilinearGrid {
  kFromKerasVersion,  // half-pixel for files saved by Keras 2.4 or later; others are refused,
                      // since Keras 2.0-2.3 ran on either TensorFlow and the file does not say
  kHalfPixel,
  kAsymmetric,
};

struct KerasImportOptions {
  // Path of a JSON file holding the architecture (`model.to_json()`). Required for weights-only
  // files; replaces the file's own `model_config` when given.
  std::string architecture_json;
  KerasBilinearGrid bilinear_grid = KerasBilinearGrid::kFromKerasVersion;
};

struct KerasImportResult {
  ModelSpec spec;
  // What the importer decided that a user should know (nested multi-GPU model exported, crop
  // kept explicit, ...), one sentence each.
  std::vector<std::string> notes;
};

// Fills layers, input (channels, built size), output channels and producer (format "keras-h5",
// file name, SHA-256 of the .h5). Name, preprocessing and camera keep ModelSpec's defaults.
Result<KerasImportResult> ImportKerasH5(const std::string& path,
                                        const KerasImportOptions& options = {});

// ImportKerasH5 on an HDF5 file image held in memory (read through HDF5's core driver, never
// touching the disk): `label` stands for the path in messages and gives producer.source_file
// its base name; the SHA-256 is of `image`.
Result<KerasImportResult> ImportKerasH5FromMemory(std::string_view image, const std::string& label,
                                                  const KerasImportOptions& options = {});

}  // namespace sfrt::exporter
