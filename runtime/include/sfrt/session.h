// Session: runs a Model's forward pass with all memory planned at creation.
//
// Create() infers every layer's shape for the largest input the session must accept
// (SessionOptions::max_height x max_width), plans one arena for all intermediate tensors
// (see memory_planner.h) and allocates it once. Run() accepts any input size up to that maximum
// and performs no heap allocation, no I/O and takes no lock on success.
//
// Ownership: a Session shares ownership of its Model; the input and output buffers belong to the
// caller and are only accessed during Run().
// Thread-safety: a Session is not thread-safe (Run() writes its arena). Use one Session per
// thread; Sessions created from the same Model share its weights.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "sfrt/model.h"
#include "sfrt/shapes.h"
#include "sfrt/status.h"

namespace sfrt {

struct SessionOptions {
  int max_height = 540;
  int max_width = 960;
};

// Where each planned tensor lives in the arena (for `--print-plan` and tests).
struct PlannedTensor {
  int producer = -1;       // index of the layer that writes it
  int last_consumer = -1;  // index of the last layer that reads it
  size_t offset = 0;       // bytes from the arena start
  size_t bytes = 0;        // at the maximum input size
};

class Session {
 public:
  static Result<std::unique_ptr<Session>> Create(std::shared_ptr<const Model> model,
                                                 const SessionOptions& options);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Output shape for an input of height x width (no allocation).
  Result<TensorShape> OutputShape(int height, int width) const;

  // input: height x width x input channels, NHWC float32 in the model's channel order.
  // output: OutputShape(height, width).elements() floats (or more), NHWC.
  // Fails (allocating only for the message) if the size exceeds the planned maximum or a buffer
  // is too small.
  Status Run(std::span<const float> input, int height, int width, std::span<float> output);

  const Model& model() const { return *model_; }
  const SessionOptions& options() const { return options_; }
  size_t arena_bytes() const { return arena_bytes_; }
  std::span<const PlannedTensor> plan() const { return plan_; }

 private:
  Session() = default;
  std::shared_ptr<const Model> model_;
  SessionOptions options_;
  std::vector<PlannedTensor> plan_;      // one per layer output, except the last and crops
  std::vector<LayerGeometry> geometry_;  // scratch for Run(), sized at creation
  std::vector<int> tensor_of_layer_;     // layer -> index into plan_ (-1: none)
  size_t arena_bytes_ = 0;
  float* arena_ = nullptr;  // 64-byte aligned, arena_bytes_ long
};

}  // namespace sfrt
