#include "sfrt/session.h"

#include <cstdlib>
#include <cstring>

#include "kernels/ref/conv2d_ref.h"
#include "kernels/ref/resample_ref.h"
#include "memory_planner.h"

namespace sfrt {

Session::~Session() { std::free(arena_); }

Result<std::unique_ptr<Session>> Session::Create(std::shared_ptr<const Model> model,
                                                 const SessionOptions& options) {
  if (model == nullptr) return Status::Error("Session::Create: no model");
  if (options.max_height <= 0 || options.max_width <= 0) {
    return Status::Error("Session::Create: maximum input size " +
                         std::to_string(options.max_height) + "x" +
                         std::to_string(options.max_width) + " is not positive");
  }
  std::unique_ptr<Session> session(new Session());
  session->model_ = std::move(model);
  session->options_ = options;
  const Model& m = *session->model_;
  const auto layers = m.layers();
  const int n = static_cast<int>(layers.size());

  session->geometry_.resize(layers.size());
  Status s = InferGeometry(m, options.max_height, options.max_width, session->geometry_);
  if (!s.ok()) {
    return Status::Error("planning for the maximum input size " +
                         std::to_string(options.max_height) + "x" +
                         std::to_string(options.max_width) + ": " + s.message());
  }

  // Every layer but the last writes a tensor of its own, except a crop, which is a view of its
  // input. A tensor lives until the first layer after it that is not a crop has read it.
  std::vector<BufferRequest> requests;
  session->tensor_of_layer_.assign(layers.size(), -1);
  for (int i = 0; i + 1 < n; ++i) {
    if (layers[i].kind == LayerKind::kCrop) continue;
    int reader = i + 1;
    while (reader < n - 1 && layers[reader].kind == LayerKind::kCrop) ++reader;
    session->tensor_of_layer_[i] = static_cast<int>(requests.size());
    requests.push_back({session->geometry_[i].output.elements() * sizeof(float), i, reader});
  }
  const ArenaPlan plan = PlanArena(requests);
  session->plan_.resize(requests.size());
  for (size_t t = 0; t < requests.size(); ++t) {
    session->plan_[t] = {requests[t].first_use, requests[t].last_use, plan.offsets[t],
                         requests[t].bytes};
  }
  session->arena_bytes_ = plan.total_bytes;
  if (plan.total_bytes > 0) {
    session->arena_ = static_cast<float*>(std::aligned_alloc(kArenaAlignment, plan.total_bytes));
    if (session->arena_ == nullptr) {
      return Status::Error("cannot allocate the " + std::to_string(plan.total_bytes) +
                           "-byte arena for " + std::to_string(options.max_height) + "x" +
                           std::to_string(options.max_width) + " inputs");
    }
  }
  return session;
}

Result<TensorShape> Session::OutputShape(int height, int width) const {
  if (height > options_.max_height || width > options_.max_width) {
    return Status::Error("input " + std::to_string(height) + "x" + std::to_string(width) +
                         " exceeds the session's maximum " + std::to_string(options_.max_height) +
                         "x" + std::to_string(options_.max_width));
  }
  // Run() keeps the geometry scratch for itself; this is a const query, so use a copy.
  std::vector<LayerGeometry> geometry(geometry_.size());
  Status s = InferGeometry(*model_, height, width, geometry);
  if (!s.ok()) return s;
  return geometry.back().output;
}

Status Session::Run(std::span<const float> input, int height, int width, std::span<float> output) {
  if (height <= 0 || width <= 0 || height > options_.max_height || width > options_.max_width) {
    return Status::Error("input " + std::to_string(height) + "x" + std::to_string(width) +
                         " is outside the session's planned range 1x1.." +
                         std::to_string(options_.max_height) + "x" +
                         std::to_string(options_.max_width));
  }
  if (Status s = InferGeometry(*model_, height, width, geometry_); !s.ok()) return s;
  const TensorShape in_shape = geometry_.front().input;
  const TensorShape out_shape = geometry_.back().output;
  if (input.size() < in_shape.elements()) {
    return Status::Error("input buffer holds " + std::to_string(input.size()) + " floats; " +
                         std::to_string(height) + "x" + std::to_string(width) + "x" +
                         std::to_string(in_shape.channels) + " needs " +
                         std::to_string(in_shape.elements()));
  }
  if (output.size() < out_shape.elements()) {
    return Status::Error("output buffer holds " + std::to_string(output.size()) + " floats; " +
                         "the output needs " + std::to_string(out_shape.elements()));
  }

  const auto layers = model_->layers();
  const size_t n = layers.size();
  ConstTensorView cur{input.data(), in_shape.height, in_shape.width, in_shape.channels,
                      static_cast<ptrdiff_t>(in_shape.width) * in_shape.channels};
  for (size_t i = 0; i < n; ++i) {
    const LayerDesc& layer = layers[i];
    const LayerGeometry& g = geometry_[i];
    const bool last = i + 1 == n;
    if (layer.kind == LayerKind::kCrop) {
      ConstTensorView view = cur;
      view.data = cur.pixel(g.crop.top, g.crop.left);
      view.height = g.output.height;
      view.width = g.output.width;
      if (last) {
        ref::Copy(view,
                  DenseView(output.data(), g.output.height, g.output.width, g.output.channels));
      }
      cur = view;
      continue;
    }
    float* dst =
        last ? output.data()
             : arena_ + plan_[static_cast<size_t>(tensor_of_layer_[i])].offset / sizeof(float);
    const TensorView out = DenseView(dst, g.output.height, g.output.width, g.output.channels);
    if (layer.kind == LayerKind::kConv2D) {
      ref::Conv2d(cur, layer.conv, g.pads, out);
    } else {
      ref::UpsampleNearest(cur, layer.upsample.factor_h, layer.upsample.factor_w, out);
    }
    cur = out;
  }
  return Status::Ok();
}

}  // namespace sfrt
