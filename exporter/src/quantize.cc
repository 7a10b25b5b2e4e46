#include "sfrt/exporter/quantize.h"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <thread>
#include <utility>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/layer_kinds.h"
#include "sfrt/model.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/sha256.h"
#include "sfrt/shapes.h"

namespace sfrt::exporter {
namespace {

constexpr int kBins = 4096;
// Float32 layer outputs are kept between the measurements of kAuto up to this many bytes.
constexpr size_t kMaxCachedBytes = size_t{256} << 20;
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string Sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2e", v);
  return buf;
}

std::span<const float> FrameValues(const CalibrationSet& data, int frame) {
  const size_t n = static_cast<size_t>(data.height) * static_cast<size_t>(data.width) *
                   static_cast<size_t>(data.channels);
  return {data.values.data() + static_cast<size_t>(frame) * n, n};
}

// RMS(diff) / RMS(reference) from the sums of squares: 0 when both are 0, infinity when only the
// reference is.
double Relative(double diff, double reference) {
  if (reference > 0) return diff / reference;
  return diff > 0 ? kInf : 0.0;
}

// The values one activation tensor takes over the calibration set: pass 1 its range, pass 2 a
// histogram over that range.
class TensorStats {
 public:
  void AddRange(std::span<const float> values) {
    for (float v : values) {
      min_ = std::min(min_, static_cast<double>(v));
      max_ = std::max(max_, static_cast<double>(v));
    }
  }

  void AddHistogram(std::span<const float> values) {
    if (bins_.empty()) bins_.assign(kBins, 0);
    count_ += values.size();
    if (!(max_ > min_)) {
      bins_[0] += values.size();
      return;
    }
    const double per_unit = kBins / (max_ - min_);
    for (float v : values) {
      const double b = std::floor((static_cast<double>(v) - min_) * per_unit);
      const int bin = b < 0 ? 0 : (b >= kBins ? kBins - 1 : static_cast<int>(b));
      ++bins_[static_cast<size_t>(bin)];
    }
  }

  // Whether pass 1 saw any value.
  bool Observed() const { return min_ <= max_; }

  // The bin edges around the central `percentile` percent of the values (quantize.h).
  std::pair<double, double> Range(double percentile) const {
    if (count_ == 0 || !(max_ > min_)) return {std::min(min_, 0.0), std::max(max_, 0.0)};
    const auto rank = std::clamp<uint64_t>(
        static_cast<uint64_t>(std::ceil(percentile / 100.0 * static_cast<double>(count_))), 1,
        count_);
    int top = kBins - 1;
    uint64_t cum = 0;
    for (int b = 0; b < kBins; ++b) {
      cum += bins_[static_cast<size_t>(b)];
      if (cum >= rank) {
        top = b;
        break;
      }
    }
    int bottom = 0;
    cum = 0;
    for (int b = kBins - 1; b >= 0; --b) {
      cum += bins_[static_cast<size_t>(b)];
      if (cum >= rank) {
        bottom = b;
        break;
      }
    }
    const double width = (max_ - min_) / kBins;
    const double hi = top == kBins - 1 ? max_ : min_ + (top + 1) * width;
    const double lo = bottom == 0 ? min_ : min_ + bottom * width;
    return {lo, hi};
  }

  // Another worker's pass 1 (its range) or pass 2 (its histogram over this range) joined to
  // this one's: a minimum, a maximum and integer counts, so the order of the joins is no matter.
  void MergeRange(const TensorStats& other) {
    min_ = std::min(min_, other.min_);
    max_ = std::max(max_, other.max_);
  }
  void MergeHistogram(const TensorStats& other) {
    if (other.bins_.empty()) return;
    if (bins_.empty()) bins_.assign(kBins, 0);
    for (size_t b = 0; b < bins_.size(); ++b) bins_[b] += other.bins_[b];
    count_ += other.count_;
  }

 private:
  double min_ = kInf;
  double max_ = -kInf;
  std::vector<uint64_t> bins_;
  uint64_t count_ = 0;
};

struct QuantizedWeights {
  std::vector<int8_t> q;
  std::vector<float> scales;
  // A 3x3 stride-1 convolution that reads a nearest-2x upsampling: its phase kernels.
  std::vector<int8_t> phase_q;
  std::vector<float> phase_scales;
};

// Whether layer `index` is a 3x3 stride-1 convolution that reads a nearest-2x upsampling
// (with or without a crop between): the layers whose int8 form carries phase kernels (the
// loader's rule).
bool ReadsUpsampling(std::span<const LayerDesc> layers, size_t index) {
  const LayerDesc& l = layers[index];
  return l.kind == LayerKind::kConv2D && l.conv.kernel_h == 3 && l.conv.kernel_w == 3 &&
         l.conv.stride_h == 1 && l.conv.stride_w == 1 &&
         ReadsNearest2xUpsampling(layers, l.inputs[0]) >= 0;
}

// The tensor whose values convolution `conv` reads: its input, through the nearest upsamplings
// and crops before it (which only repeat or drop values). A layer index, or kModelInput.
int ValuesRead(std::span<const LayerDesc> layers, size_t conv) {
  int t = layers[conv].inputs[0];
  while (t >= 0 && (layers[static_cast<size_t>(t)].kind == LayerKind::kUpsample ||
                    layers[static_cast<size_t>(t)].kind == LayerKind::kCrop)) {
    t = layers[static_cast<size_t>(t)].inputs[0];
  }
  return t;
}

// Runs fn(frame, worker) for every frame in [0, frames) on `workers` threads (the caller's the
// first), each taking the next frame in order; done() after each frame, one call at a time.
// After a failure no further frame starts. Returns the status of the lowest frame that failed:
// every frame below it had started, so it is the one a single thread would have reported.
Status ForEachFrame(int frames, int workers, const std::function<Status(int, int)>& fn,
                    const std::function<void()>& done) {
  std::vector<Status> status(static_cast<size_t>(frames), Status::Ok());
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::mutex done_mutex;
  auto work = [&](int worker) {
    while (!failed.load()) {
      const int f = next.fetch_add(1);
      if (f >= frames) return;
      Status s = fn(f, worker);
      if (!s.ok()) failed.store(true);
      status[static_cast<size_t>(f)] = std::move(s);
      const std::lock_guard<std::mutex> lock(done_mutex);
      done();
    }
  };
  std::vector<std::thread> threads;
  for (int w = 1; w < workers; ++w) threads.emplace_back(work, w);
  work(0);
  for (std::thread& t : threads) t.join();
  for (Status& s : status) {
    if (!s.ok()) return std::move(s);
  }
  return Status::Ok();
}

Result<std::shared_ptr<const Model>> Load(const ModelSpec& spec, const std::string& label) {
  Result<std::vector<uint8_t>> bytes = SerializeModel(spec);
  if (!bytes.ok()) return Status::Error(label + ": " + bytes.message());
  return Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy, {}, label);
}

// The errors of one quantised model against float32 over the calibration set.
struct Errors {
  std::vector<double> relative_rms;  // per convolution
  std::vector<double> relative_max;  // per convolution: max |difference| / max |float32|
  double output_max_rel = 0;
  double output_rms_rel = 0;
};

// How the bias correction turns a convolution's output back into the value before its
// activation: y >= 0 ? y : y / leaky_slope (no activation: slope 1), or not at all.
struct PreActivation {
  bool invertible = false;
  float leaky_slope = 1.0f;
  double operator()(float y) const { return y >= 0.0f ? y : static_cast<double>(y) / leaky_slope; }
};

PreActivation PreActivationOf(const ConvSpec& c) {
  if (c.activation == Activation::kNone) return {true, 1.0f};
  if (c.activation == Activation::kLeakyRelu && c.leaky_slope > 0.0f) return {true, c.leaky_slope};
  return {};
}

// Runs the float32 model over the calibration set: the activation statistics, and the reference
// outputs the quantised models are measured against. Forward passes on QuantizeOptions::engine.
class Calibrator {
 public:
  Calibrator(const CalibrationSet& data, const QuantizeOptions& options,
             std::shared_ptr<const Model> fp32, std::vector<int> conv_layers)
      : data_(data),
        options_(options),
        fp32_(std::move(fp32)),
        conv_layers_(std::move(conv_layers)) {
    const auto layers = fp32_->layers();
    conv_of_layer_.assign(layers.size(), -1);
    stats_of_layer_.assign(layers.size(), -1);
    stats_.resize(1);  // the model input
    auto observe = [&](int t) {
      if (t == kModelInput || stats_of_layer_[static_cast<size_t>(t)] >= 0) return;
      stats_of_layer_[static_cast<size_t>(t)] = static_cast<int>(stats_.size());
      stats_.emplace_back();
    };
    for (size_t j = 0; j < conv_layers_.size(); ++j) {
      const auto conv = static_cast<size_t>(conv_layers_[j]);
      conv_of_layer_[conv] = static_cast<int>(j);
      observe(ValuesRead(layers, conv));
      observe(static_cast<int>(conv));
    }
  }

  Status Prepare() {
    Result<std::vector<LayerGeometry>> geometry = InferGeometry(*fp32_, data_.height, data_.width);
    if (!geometry.ok()) {
      return Status::Error("the model cannot run at the calibration frames' size " +
                           std::to_string(data_.height) + "x" + std::to_string(data_.width) + ": " +
                           geometry.message());
    }
    output_elements_ = geometry->back().output.elements();
    size_t per_frame = output_elements_;
    for (int layer : conv_layers_)
      per_frame += (*geometry)[static_cast<size_t>(layer)].output.elements();
    cache_ = per_frame * sizeof(float) * static_cast<size_t>(data_.frames) <= kMaxCachedBytes;
    fp32_sessions_.resize(static_cast<size_t>(Workers()));
    sessions_.resize(static_cast<size_t>(Workers()));
    return Status::Ok();
  }

  // Passes 1 (range) and 2 (histogram) over the float32 model, frames on Workers() threads, each
  // with its own statistics, joined after the pass.
  Status Observe() {
    const int workers = Workers();
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::vector<TensorStats>> local(
          static_cast<size_t>(workers),
          pass == 0 ? std::vector<TensorStats>(stats_.size()) : stats_);
      std::vector<std::vector<float>> outputs(static_cast<size_t>(workers),
                                              std::vector<float>(output_elements_));
      int frames_done = 0;
      const auto frame = [&](int f, int worker) -> Status {
        std::vector<TensorStats>& stats = local[static_cast<size_t>(worker)];
        const std::span<const float> input = FrameValues(data_, f);
        pass == 0 ? stats[0].AddRange(input) : stats[0].AddHistogram(input);
        Status bad = Status::Ok();
        const LayerObserver observer = [&](int layer, const TensorShape&,
                                           std::span<const float> values) {
          const int j = stats_of_layer_[static_cast<size_t>(layer)];
          if (j < 0 || !bad.ok()) return;
          if (pass == 0) {
            for (float v : values) {
              if (std::isfinite(v)) continue;
              bad = Status::Error("layer " + std::to_string(layer) + " '" +
                                  fp32_->layers()[static_cast<size_t>(layer)].name +
                                  "' gives a non-finite value on calibration frame " +
                                  std::to_string(f) + "; its range cannot be quantised");
              return;
            }
            stats[static_cast<size_t>(j)].AddRange(values);
          } else {
            stats[static_cast<size_t>(j)].AddHistogram(values);
          }
        };
        if (Status s =
                Forward(fp32_, worker, input, outputs[static_cast<size_t>(worker)], observer);
            !s.ok()) {
          return s;
        }
        return bad;
      };
      if (Status s =
              ForEachFrame(data_.frames, workers, frame,
                           [&] { Progress(pass == 0 ? "range" : "histogram", frames_done++); });
          !s.ok()) {
        return s;
      }
      for (const std::vector<TensorStats>& stats : local) {
        for (size_t k = 0; k < stats_.size(); ++k) {
          pass == 0 ? stats_[k].MergeRange(stats[k]) : stats_[k].MergeHistogram(stats[k]);
        }
      }
    }
    // Every tensor a quantisation comes from was shown (a session shows each convolution and
    // Concat; Session::RunObserved).
    for (size_t t = 0; t < stats_of_layer_.size(); ++t) {
      const int k = stats_of_layer_[t];
      if (k >= 0 && !stats_[static_cast<size_t>(k)].Observed()) {
        return Status::Error("calibration saw no value of layer " + std::to_string(t) + " '" +
                             fp32_->layers()[t].name + "' (internal error)");
      }
    }
    return Status::Ok();
  }

  // The quantisation of what the convolutions `members` read (ValuesRead), over the union of
  // their ranges, and of what convolution j writes.
  QuantParams InputQuant(std::span<const size_t> members, double percentile) const {
    double lo = 0, hi = 0;
    for (size_t j : members) {
      const int t = ValuesRead(fp32_->layers(), static_cast<size_t>(conv_layers_[j]));
      const int k = t == kModelInput ? 0 : stats_of_layer_[static_cast<size_t>(t)];
      const auto [l, h] = stats_[static_cast<size_t>(k)].Range(percentile);
      lo = std::min(lo, l);
      hi = std::max(hi, h);
    }
    return ActivationQuantParams(lo, hi);
  }
  QuantParams OutputQuant(size_t j, double percentile) const {
    return TensorQuant(conv_layers_[j], percentile);
  }

  // The errors of `quantised` over the calibration set, frames on Workers() threads; each
  // frame's sums are added in frame order, so the thread count does not change a bit.
  Result<Errors> Measure(const std::shared_ptr<const Model>& quantised) {
    const size_t convs = conv_layers_.size();
    struct FrameSums {
      explicit FrameSums(size_t convs)
          : diff2(convs, 0.0), ref2(convs, 0.0), max_diff(convs, 0.0), max_ref(convs, 0.0) {}
      std::vector<double> diff2, ref2, max_diff, max_ref;  // per convolution
      double out_diff2 = 0, out_ref2 = 0, out_max_diff = 0, out_max_ref = 0;
    };
    std::vector<FrameSums> sums(static_cast<size_t>(data_.frames), FrameSums(convs));
    if (cache_ && references_.empty()) references_.resize(static_cast<size_t>(data_.frames));
    const int workers = Workers();
    std::vector<std::vector<float>> outputs(static_cast<size_t>(workers),
                                            std::vector<float>(output_elements_));
    // Uncached, each worker's float32 tensors of the frame it runs, reused frame after frame.
    std::vector<Reference> computed(cache_ ? 0 : static_cast<size_t>(workers));
    int frames_done = 0;
    const auto frame = [&](int f, int worker) -> Status {
      const std::span<const float> input = FrameValues(data_, f);
      Reference& ref =
          cache_ ? references_[static_cast<size_t>(f)] : computed[static_cast<size_t>(worker)];
      if (!cache_ || ref.output.empty()) {
        ref.convs.resize(convs);
        ref.output.resize(output_elements_);
        const LayerObserver keep = [&](int layer, const TensorShape&,
                                       std::span<const float> values) {
          const int j = conv_of_layer_[static_cast<size_t>(layer)];
          if (j >= 0) ref.convs[static_cast<size_t>(j)].assign(values.begin(), values.end());
        };
        if (Status s = Forward(fp32_, worker, input, ref.output, keep); !s.ok()) {
          ref.output.clear();
          return s;
        }
      }
      FrameSums& e = sums[static_cast<size_t>(f)];
      const LayerObserver compare = [&](int layer, const TensorShape&,
                                        std::span<const float> values) {
        const int j = conv_of_layer_[static_cast<size_t>(layer)];
        if (j < 0) return;
        const std::vector<float>& r = ref.convs[static_cast<size_t>(j)];
        const auto jj = static_cast<size_t>(j);
        for (size_t k = 0; k < values.size() && k < r.size(); ++k) {
          const double d = static_cast<double>(values[k]) - r[k];
          e.diff2[jj] += d * d;
          e.ref2[jj] += static_cast<double>(r[k]) * r[k];
          e.max_diff[jj] = std::max(e.max_diff[jj], std::fabs(d));
          e.max_ref[jj] = std::max(e.max_ref[jj], std::fabs(static_cast<double>(r[k])));
        }
      };
      std::vector<float>& output = outputs[static_cast<size_t>(worker)];
      if (Status s = Forward(quantised, worker, input, output, compare); !s.ok()) {
        return s;
      }
      for (size_t k = 0; k < output.size(); ++k) {
        const double r = ref.output[k];
        const double d = static_cast<double>(output[k]) - r;
        e.out_diff2 += d * d;
        e.out_ref2 += r * r;
        e.out_max_diff = std::max(e.out_max_diff, std::fabs(d));
        e.out_max_ref = std::max(e.out_max_ref, std::fabs(r));
      }
      return Status::Ok();
    };
    if (Status s =
            ForEachFrame(data_.frames, workers, frame, [&] { Progress("measure", frames_done++); });
        !s.ok()) {
      return s;
    }
    FrameSums total(convs);
    for (const FrameSums& e : sums) {
      for (size_t j = 0; j < convs; ++j) {
        total.diff2[j] += e.diff2[j];
        total.ref2[j] += e.ref2[j];
        total.max_diff[j] = std::max(total.max_diff[j], e.max_diff[j]);
        total.max_ref[j] = std::max(total.max_ref[j], e.max_ref[j]);
      }
      total.out_diff2 += e.out_diff2;
      total.out_ref2 += e.out_ref2;
      total.out_max_diff = std::max(total.out_max_diff, e.out_max_diff);
      total.out_max_ref = std::max(total.out_max_ref, e.out_max_ref);
    }
    Errors errors;
    for (size_t j = 0; j < convs; ++j) {
      errors.relative_rms.push_back(Relative(std::sqrt(total.diff2[j]), std::sqrt(total.ref2[j])));
      errors.relative_max.push_back(Relative(total.max_diff[j], total.max_ref[j]));
    }
    errors.output_max_rel = Relative(total.out_max_diff, total.out_max_ref);
    errors.output_rms_rel = Relative(std::sqrt(total.out_diff2), std::sqrt(total.out_ref2));
    return errors;
  }

  // For each convolution j that inverse[j] can invert, the mean over the calibration frames and
  // pixels of each output channel's value before its activation, inverse[j] of what `model`'s
  // forward pass shows of it; an empty vector for the others. Frames on Workers() threads; each
  // frame's sums are added in frame order, so the thread count does not change a bit.
  Result<std::vector<std::vector<double>>> PreActivationMeans(
      const std::shared_ptr<const Model>& model, std::span<const PreActivation> inverse,
      const char* pass) {
    const size_t convs = conv_layers_.size();
    struct FrameSums {
      std::vector<std::vector<double>> sums;  // per convolution, per channel
      std::vector<size_t> pixels;             // per convolution
    };
    std::vector<FrameSums> frames(static_cast<size_t>(data_.frames));
    const int workers = Workers();
    std::vector<std::vector<float>> outputs(static_cast<size_t>(workers),
                                            std::vector<float>(output_elements_));
    int frames_done = 0;
    const auto frame = [&](int f, int worker) -> Status {
      FrameSums& e = frames[static_cast<size_t>(f)];
      e.sums.assign(convs, {});
      e.pixels.assign(convs, 0);
      const LayerObserver add = [&](int layer, const TensorShape& shape,
                                    std::span<const float> values) {
        const int j = conv_of_layer_[static_cast<size_t>(layer)];
        if (j < 0 || !inverse[static_cast<size_t>(j)].invertible) return;
        const PreActivation& pre = inverse[static_cast<size_t>(j)];
        std::vector<double>& sums = e.sums[static_cast<size_t>(j)];
        const auto channels = static_cast<size_t>(shape.channels);
        sums.assign(channels, 0.0);
        for (size_t k = 0; k < values.size(); ++k) sums[k % channels] += pre(values[k]);
        e.pixels[static_cast<size_t>(j)] = values.size() / channels;
      };
      return Forward(model, worker, FrameValues(data_, f), outputs[static_cast<size_t>(worker)],
                     add);
    };
    if (Status s =
            ForEachFrame(data_.frames, workers, frame, [&] { Progress(pass, frames_done++); });
        !s.ok()) {
      return s;
    }
    std::vector<std::vector<double>> means(convs);
    for (size_t j = 0; j < convs; ++j) {
      if (!inverse[j].invertible) continue;
      size_t pixels = 0;
      for (const FrameSums& e : frames) {
        if (e.sums[j].empty()) {
          return Status::Error("calibration saw no value of convolution " + std::to_string(j) +
                               " (internal error)");
        }
        means[j].resize(e.sums[j].size(), 0.0);
        for (size_t c = 0; c < e.sums[j].size(); ++c) means[j][c] += e.sums[j][c];
        pixels += e.pixels[j];
      }
      for (double& m : means[j]) m /= static_cast<double>(pixels);
    }
    return means;
  }

 private:
  struct Reference {
    std::vector<std::vector<float>> convs;
    std::vector<float> output;
  };

  // The quantisation of layer t's output (kModelInput: the model input's), an observed tensor.
  QuantParams TensorQuant(int t, double percentile) const {
    const int k = t == kModelInput ? 0 : stats_of_layer_[static_cast<size_t>(t)];
    const auto [lo, hi] = stats_[static_cast<size_t>(k)].Range(percentile);
    return ActivationQuantParams(lo, hi);
  }

  // One forward pass of `model` on `input` (a calibration frame) for worker `worker`, showing
  // `observer` its layers: on the reference kernels, or on the worker's Session for the model
  // (for the float32 model, or the quantised one being measured; made on first use).
  Status Forward(const std::shared_ptr<const Model>& model, int worker,
                 std::span<const float> input, std::span<float> output,
                 const LayerObserver& observer) {
    if (options_.engine == CalibrationEngine::kReference) {
      return RunReferenceForward(*model, input, data_.height, data_.width, output, observer);
    }
    std::unique_ptr<Session>& session =
        (model == fp32_ ? fp32_sessions_ : sessions_)[static_cast<size_t>(worker)];
    // A session keeps its model alive, so another model cannot have its address.
    if (session == nullptr || &session->model() != model.get()) {
      session.reset();  // its arena goes before the next one is allocated
      SessionOptions session_options;
      session_options.max_height = data_.height;
      session_options.max_width = data_.width;
      session_options.threads = std::max(1, options_.threads / Workers());
      Result<std::unique_ptr<Session>> created = Session::Create(model, session_options);
      if (!created.ok()) return Status::Error("calibration session: " + created.message());
      session = std::move(created).value();
    }
    return session->RunObserved(input, data_.height, data_.width, output, observer);
  }

  void Progress(const char* pass, int frame) const {
    if (options_.progress) options_.progress(pass, frame + 1, data_.frames);
  }

  // Threads that run frames at once: QuantizeOptions::threads, at most one per frame.
  int Workers() const { return std::max(1, std::min(options_.threads, data_.frames)); }

  const CalibrationSet& data_;
  const QuantizeOptions& options_;
  std::shared_ptr<const Model> fp32_;
  std::vector<int> conv_layers_;
  std::vector<int> conv_of_layer_;
  std::vector<int> stats_of_layer_;  // index into stats_ (0: the model input), -1 when unobserved
  std::vector<TensorStats> stats_;
  size_t output_elements_ = 0;
  bool cache_ = false;
  std::vector<Reference> references_;  // per frame, when cache_
  // CalibrationEngine::kSession: per worker, a session of the float32 model and one of the
  // quantised model being measured.
  std::vector<std::unique_ptr<Session>> fp32_sessions_;
  std::vector<std::unique_ptr<Session>> sessions_;
};

// `fp32` with each convolution in its precision: int8 quantised, bf16 marked.
ModelSpec BuildSpec(const ModelSpec& fp32, const std::vector<Precision>& precision,
                    const std::vector<QuantParams>& input_quant,
                    const std::vector<QuantParams>& output_quant,
                    const std::vector<QuantizedWeights>& weights) {
  ModelSpec out = fp32;
  size_t j = 0;
  for (LayerSpec& layer : out.layers) {
    auto* c = std::get_if<ConvSpec>(&layer);
    if (c == nullptr) continue;
    if (precision[j] == Precision::kBFloat16) c->precision = Precision::kBFloat16;
    if (precision[j] == Precision::kInt8) {
      c->precision = Precision::kInt8;
      c->weights_hwio.clear();
      c->weights_hwio.shrink_to_fit();
      c->weights_q = weights[j].q;
      c->weight_scales = weights[j].scales;
      c->input_quant = input_quant[j];
      c->output_quant = output_quant[j];
      c->phase_weights_q = weights[j].phase_q;
      c->phase_scales = weights[j].phase_scales;
    }
    ++j;
  }
  return out;
}

// Empirical bias correction (QuantizeOptions::bias_correction): each int8 convolution whose
// activation PreActivationOf inverts, in order, has its bias moved per output channel by the
// mean of its pre-activation error against float32 over the calibration frames, measured on the
// quantised model with the corrections before it made. The biases are written into `spec` (the
// float32 model the quantised one is built from).
Status CorrectBiases(Calibrator& calibrator, const std::shared_ptr<const Model>& fp32,
                     std::span<const int> conv_layers, const std::vector<Precision>& precision,
                     const std::vector<QuantParams>& input_quant,
                     const std::vector<QuantParams>& output_quant,
                     const std::vector<QuantizedWeights>& weights, ModelSpec* spec) {
  const size_t convs = conv_layers.size();
  auto conv = [&](size_t j) -> ConvSpec& {
    return std::get<ConvSpec>(spec->layers[static_cast<size_t>(conv_layers[j])]);
  };
  std::vector<PreActivation> inverse(convs);
  for (size_t j = 0; j < convs; ++j) {
    if (precision[j] == Precision::kInt8) inverse[j] = PreActivationOf(conv(j));
  }
  Result<std::vector<std::vector<double>>> reference =
      calibrator.PreActivationMeans(fp32, inverse, "bias correction: float32");
  if (!reference.ok()) return reference.status();
  for (size_t j = 0; j < convs; ++j) {
    if (!inverse[j].invertible) continue;
    std::vector<PreActivation> only(convs);
    only[j] = inverse[j];
    Result<std::shared_ptr<const Model>> quantised = Load(
        BuildSpec(*spec, precision, input_quant, output_quant, weights), "the quantised model");
    if (!quantised.ok()) return quantised.status();
    const std::string pass = "bias correction: " + conv(j).name;
    Result<std::vector<std::vector<double>>> means =
        calibrator.PreActivationMeans(*quantised, only, pass.c_str());
    if (!means.ok()) return means.status();
    std::vector<float>& bias = conv(j).bias;
    for (size_t o = 0; o < bias.size(); ++o) {
      bias[o] -= static_cast<float>((*means)[j][o] - (*reference)[j][o]);
    }
  }
  return Status::Ok();
}

}  // namespace

Status CheckCalibrationSet(const CalibrationSet& data, int channels) {
  if (data.frames <= 0) return Status::Error("the calibration set is empty (no frames)");
  if (data.height <= 0 || data.width <= 0) {
    return Status::Error("calibration frames are " + std::to_string(data.height) + "x" +
                         std::to_string(data.width) + "; both sides must be positive");
  }
  if (data.channels != channels) {
    return Status::Error("calibration frames have " + std::to_string(data.channels) +
                         " channels but the model's input has " + std::to_string(channels));
  }
  const size_t per_frame = static_cast<size_t>(data.height) * static_cast<size_t>(data.width) *
                           static_cast<size_t>(data.channels);
  if (data.values.size() != per_frame * static_cast<size_t>(data.frames)) {
    return Status::Error("the calibration set holds " + std::to_string(data.values.size()) +
                         " values; " + std::to_string(data.frames) + " frames of " +
                         std::to_string(data.height) + "x" + std::to_string(data.width) + "x" +
                         std::to_string(data.channels) + " need " +
                         std::to_string(per_frame * static_cast<size_t>(data.frames)));
  }
  for (size_t i = 0; i < data.values.size(); ++i) {
    const float v = data.values[i];
    if (std::isfinite(v)) continue;
    const size_t c = i % static_cast<size_t>(data.channels);
    const size_t pixel = i / static_cast<size_t>(data.channels);
    const size_t x = pixel % static_cast<size_t>(data.width);
    const size_t y = pixel / static_cast<size_t>(data.width) % static_cast<size_t>(data.height);
    return Status::Error(
        "calibration frame " + std::to_string(i / per_frame) + ", element [" + std::to_string(y) +
        ", " + std::to_string(x) + ", " + std::to_string(c) + "] (flat index " + std::to_string(i) +
        ") is " + (std::isnan(v) ? "NaN" : "infinite") + "; calibration values must be finite");
  }
  for (int f = 0; f < data.frames; ++f) {
    const std::span<const float> v = FrameValues(data, f);
    if (std::any_of(v.begin(), v.end(), [&](float x) { return x != v.front(); })) {
      return Status::Ok();
    }
  }
  return Status::Error("all " + std::to_string(data.frames) +
                       " calibration frames are constant (one value throughout each); "
                       "quantisation ranges need real inputs");
}

Result<CalibrationMethod> ParseCalibrationMethod(const std::string& method) {
  if (method == "minmax") return CalibrationMethod{100.0, "minmax"};
  const std::string prefix = "percentile:";
  double p = 0;
  bool ok = method.compare(0, prefix.size(), prefix) == 0 && method.size() > prefix.size();
  if (ok) {
    const char* begin = method.data() + prefix.size();
    const char* end = method.data() + method.size();
    const auto [ptr, ec] = std::from_chars(begin, end, p);
    ok = ec == std::errc() && ptr == end && p >= 50.0 && p <= 100.0;
  }
  if (!ok) {
    return Status::Error("calibration method '" + method +
                         "': expected percentile:P with P in 50..100, or minmax");
  }
  char text[64];
  std::snprintf(text, sizeof(text), "percentile:%g", p);
  return CalibrationMethod{p, text};
}

QuantParams ActivationQuantParams(double lo, double hi) {
  lo = std::min(lo, 0.0);
  hi = std::max(hi, 0.0);
  const auto scale = static_cast<float>((hi - lo) / 255.0);
  if (!(scale >= std::numeric_limits<float>::min()) || !std::isfinite(scale)) return {1.0f, 0};
  const double zero = std::nearbyint(-lo / static_cast<double>(scale));
  return {scale, static_cast<int>(std::clamp(zero, 0.0, 255.0))};
}

void QuantizeWeights(std::span<const float> hwio, int out_channels, std::vector<int8_t>* q,
                     std::vector<float>* scales) {
  const auto outs = static_cast<size_t>(out_channels);
  scales->assign(outs, 1.0f);
  q->assign(hwio.size(), 0);
  for (size_t o = 0; o < outs; ++o) {
    float max_abs = 0;
    for (size_t k = o; k < hwio.size(); k += outs) max_abs = std::max(max_abs, std::fabs(hwio[k]));
    if (max_abs == 0) continue;  // scale 1, every q 0
    const float scale = std::max(max_abs / 127.0f, std::numeric_limits<float>::min());
    (*scales)[o] = scale;
    for (size_t k = o; k < hwio.size(); k += outs) {
      const double r = std::nearbyint(static_cast<double>(hwio[k]) / scale);
      (*q)[k] = static_cast<int8_t>(std::clamp(r, -127.0, 127.0));
    }
  }
}

void QuantizePhaseWeights(std::span<const float> hwio3x3, int in_channels, int out_channels,
                          std::vector<int8_t>* q, std::vector<float>* scales) {
  const size_t per_tap = static_cast<size_t>(in_channels) * static_cast<size_t>(out_channels);
  // The 3x3 taps (along one axis) that phase `ph`'s tap `t` sums.
  auto first = [](int ph, int t) { return ph == 0 ? (t == 0 ? 0 : 2) : (t == 0 ? 0 : 1); };
  auto last = [](int ph, int t) { return ph == 0 ? (t == 0 ? 1 : 2) : (t == 0 ? 0 : 2); };
  q->clear();
  scales->clear();
  std::vector<float> phase(4 * per_tap);
  for (int py = 0; py < 2; ++py) {
    for (int px = 0; px < 2; ++px) {
      std::fill(phase.begin(), phase.end(), 0.0f);
      for (int ty = 0; ty < 2; ++ty) {
        for (int tx = 0; tx < 2; ++tx) {
          float* dst = phase.data() + static_cast<size_t>(ty * 2 + tx) * per_tap;
          for (int ky = first(py, ty); ky <= last(py, ty); ++ky) {
            for (int kx = first(px, tx); kx <= last(px, tx); ++kx) {
              const float* src = hwio3x3.data() + static_cast<size_t>(ky * 3 + kx) * per_tap;
              for (size_t k = 0; k < per_tap; ++k) dst[k] += src[k];
            }
          }
        }
      }
      std::vector<int8_t> pq;
      std::vector<float> ps;
      QuantizeWeights(phase, out_channels, &pq, &ps);
      q->insert(q->end(), pq.begin(), pq.end());
      scales->insert(scales->end(), ps.begin(), ps.end());
    }
  }
}

std::vector<int> SharedScaleGroups(std::span<const LayerDesc> layers,
                                   std::span<const int> conv_layers) {
  // The convolution outputs the values convolution j reads come from.
  auto sources = [&](int conv) {
    std::vector<int> found;
    std::vector<int> pending = {layers[static_cast<size_t>(conv)].inputs[0]};
    while (!pending.empty()) {
      const int t = pending.back();
      pending.pop_back();
      if (t == kModelInput) continue;
      const LayerDesc& l = layers[static_cast<size_t>(t)];
      if (l.kind == LayerKind::kUpsample || l.kind == LayerKind::kCrop) {
        pending.push_back(l.inputs[0]);
      } else if (l.kind == LayerKind::kConcat) {
        pending.insert(pending.end(), l.inputs.begin(), l.inputs.end());
      } else if (l.kind == LayerKind::kConv2D) {
        found.push_back(t);
      }
    }
    return found;
  };
  std::vector<int> group(conv_layers.size());
  std::iota(group.begin(), group.end(), 0);
  std::vector<int> first_reader(layers.size(), -1);  // per source: a convolution reading it
  for (size_t j = 0; j < conv_layers.size(); ++j) {
    for (int source : sources(conv_layers[j])) {
      int& reader = first_reader[static_cast<size_t>(source)];
      if (reader < 0) {
        reader = static_cast<int>(j);
        continue;
      }
      // Merge j's group into the reader's: renumber to the smaller number.
      const int from = std::max(group[j], group[static_cast<size_t>(reader)]);
      const int to = std::min(group[j], group[static_cast<size_t>(reader)]);
      for (int& g : group) {
        if (g == from) g = to;
      }
    }
  }
  return group;
}

std::string CalibrationDataSha256(const CalibrationSet& data) {
  Sha256 sha;
  sha.Update(data.values.data(), data.values.size() * sizeof(float));
  return sha.FinishHex();
}

namespace {

Status CheckQuantizeOptions(const QuantizeOptions& options) {
  if (options.threads < 1) {
    return Status::Error("calibration threads " + std::to_string(options.threads) +
                         ": must be at least 1");
  }
  if (options.mode == QuantizeMode::kAuto &&
      !(options.accuracy_budget >= 0 && std::isfinite(options.accuracy_budget))) {
    return Status::Error("accuracy budget " + Sci(options.accuracy_budget) +
                         ": must be a finite number >= 0");
  }
  if (options.bias_correction && options.mode != QuantizeMode::kInt8) {
    return Status::Error(
        "bias correction is for int8 quantisation (every convolution int8), "
        "not the auto mode");
  }
  return Status::Ok();
}

bool Reduced(Precision p) { return p != Precision::kFloat32; }

// The model's convolutions: their layer indices, names and first precisions (int8 where it can
// be, float32 otherwise: ReducibleConv).
struct ConvList {
  std::vector<int> layers;
  std::vector<std::string> names;
  std::vector<Precision> precision;
};

Result<ConvList> ListConvs(const ModelSpec& model) {
  ConvList convs;
  for (size_t i = 0; i < model.layers.size(); ++i) {
    const auto* c = std::get_if<ConvSpec>(&model.layers[i]);
    if (c == nullptr) continue;
    if (c->precision != Precision::kFloat32) {
      return Status::Error("layer " + std::to_string(i) + " '" + c->name + "' is already " +
                           PrecisionName(c->precision) +
                           "; quantisation starts from a float32 model");
    }
    convs.layers.push_back(static_cast<int>(i));
    convs.names.push_back(c->name);
    convs.precision.push_back(ReducibleConv(*c) ? Precision::kInt8 : Precision::kFloat32);
  }
  if (std::none_of(convs.precision.begin(), convs.precision.end(), Reduced)) {
    return Status::Error(
        "model '" + model.name + "' has no convolution to quantise" +
        (convs.layers.empty() ? std::string() : " (dilated and grouped ones run in fp32 only)"));
  }
  return convs;
}

// Each convolution's input and output ranges; the inputs of a group of convolutions that read
// the same values share one range (QuantizeOptions::shared_scales, SharedScaleGroups).
struct Ranges {
  std::vector<int> group;
  std::vector<QuantParams> input, output;
};

Ranges RangesOf(const Calibrator& calibrator, const Model& fp32, const ConvList& convs,
                const QuantizeOptions& options, double percentile) {
  Ranges r;
  r.group.resize(convs.layers.size());
  if (options.shared_scales) {
    r.group = SharedScaleGroups(fp32.layers(), convs.layers);
  } else {
    std::iota(r.group.begin(), r.group.end(), 0);
  }
  for (size_t j = 0; j < convs.layers.size(); ++j) {
    std::vector<size_t> members;
    for (size_t k = 0; k < convs.layers.size(); ++k) {
      if (r.group[k] == r.group[j]) members.push_back(k);
    }
    r.input.push_back(calibrator.InputQuant(members, percentile));
    r.output.push_back(calibrator.OutputQuant(j, percentile));
  }
  return r;
}

// The int8 weights (and phase kernels, where a convolution reads a 2x upsampling) of the
// convolutions that may be reduced.
std::vector<QuantizedWeights> WeightsOf(const ModelSpec& model, const Model& fp32,
                                        const ConvList& convs) {
  std::vector<QuantizedWeights> weights(convs.layers.size());
  for (size_t j = 0; j < convs.layers.size(); ++j) {
    if (!Reduced(convs.precision[j])) continue;
    const auto& c = std::get<ConvSpec>(model.layers[static_cast<size_t>(convs.layers[j])]);
    QuantizeWeights(c.weights_hwio, c.out_channels, &weights[j].q, &weights[j].scales);
    if (ReadsUpsampling(fp32.layers(), static_cast<size_t>(convs.layers[j]))) {
      QuantizePhaseWeights(c.weights_hwio, c.in_channels, c.out_channels, &weights[j].phase_q,
                           &weights[j].phase_scales);
    }
  }
  return weights;
}

// The auto mode's step: the int8 or bf16 convolution whose error, in the budget's metric, rose
// most over its input's (with max: a range that clips a few values shows in the largest error
// only) goes one rung up the ladder (int8 -> bf16 where the ladder has it, then -> fp32).
// Returns the line that records it.
std::string RaiseWorstLayer(const Errors& errors, const QuantizeOptions& options,
                            const std::vector<std::string>& names,
                            std::vector<Precision>& precision) {
  const bool max = options.accuracy_metric == AccuracyMetric::kMax;
  const std::vector<double>& layer_error = max ? errors.relative_max : errors.relative_rms;
  size_t worst = 0;
  double worst_rise = -kInf;
  for (size_t j = 0; j < precision.size(); ++j) {
    if (!Reduced(precision[j])) continue;
    const double rise = layer_error[j] - (j == 0 ? 0.0 : layer_error[j - 1]);
    if (rise > worst_rise) {
      worst = j;
      worst_rise = rise;
    }
  }
  const bool to_bf16 = precision[worst] == Precision::kInt8 && options.auto_bf16;
  precision[worst] = to_bf16 ? Precision::kBFloat16 : Precision::kFloat32;
  const double error = max ? errors.output_max_rel : errors.output_rms_rel;
  return names[worst] + (to_bf16 ? " to bf16" : " back to fp32") + ": output " +
         (max ? "max " : "rms ") + Sci(error) + " > budget " + Sci(options.accuracy_budget) +
         "; its relative " + (max ? "max " : "rms ") + Sci(layer_error[worst]) + " rose " +
         Sci(worst_rise) + " over its input's";
}

// What the model file records of the calibration.
CalibrationDesc DescribeCalibration(const CalibrationMethod& method, const QuantizeOptions& options,
                                    const CalibrationSet& data, const std::vector<int>& group,
                                    const ConvList& convs, const Errors& errors) {
  CalibrationDesc cal;
  // Where a group has more than one member, the ranges are shared, and the record says so.
  std::vector<int> sorted_groups = group;
  std::sort(sorted_groups.begin(), sorted_groups.end());
  const bool shared =
      std::adjacent_find(sorted_groups.begin(), sorted_groups.end()) != sorted_groups.end();
  cal.method = method.text + (shared ? ", shared scales" : "") +
               (options.bias_correction ? ", bias correction" : "");
  cal.data_sha256 = CalibrationDataSha256(data);
  cal.frames = data.frames;
  cal.height = data.height;
  cal.width = data.width;
  cal.output_max_rel = static_cast<float>(errors.output_max_rel);
  cal.output_rms_rel = static_cast<float>(errors.output_rms_rel);
  for (size_t j = 0; j < convs.layers.size(); ++j) {
    cal.layers.push_back(
        {convs.names[j], convs.precision[j], static_cast<float>(errors.relative_rms[j])});
  }
  return cal;
}

}  // namespace

Result<QuantizeResult> Quantize(const ModelSpec& model, const CalibrationSet& data,
                                const QuantizeOptions& options) {
  Result<CalibrationMethod> method = ParseCalibrationMethod(options.method);
  if (!method.ok()) return method.status();
  if (Status s = CheckQuantizeOptions(options); !s.ok()) return s;
  Result<ConvList> listed = ListConvs(model);
  if (!listed.ok()) return listed.status();
  ConvList& convs = *listed;
  if (Status s = CheckCalibrationSet(data, model.input.channels); !s.ok()) return s;

  ModelSpec fp32_spec = model;
  fp32_spec.calibration.reset();
  Result<std::shared_ptr<const Model>> fp32 = Load(fp32_spec, "the float32 model");
  if (!fp32.ok()) return fp32.status();
  Calibrator calibrator(data, options, *fp32, convs.layers);
  if (Status s = calibrator.Prepare(); !s.ok()) return s;
  if (Status s = calibrator.Observe(); !s.ok()) return s;
  const Ranges ranges = RangesOf(calibrator, **fp32, convs, options, method->percentile);
  const std::vector<QuantizedWeights> weights = WeightsOf(model, **fp32, convs);

  // The float32 model the quantised ones are built from: its biases corrected, or as given.
  ModelSpec base = fp32_spec;
  if (options.bias_correction) {
    if (Status s = CorrectBiases(calibrator, *fp32, convs.layers, convs.precision, ranges.input,
                                 ranges.output, weights, &base);
        !s.ok()) {
      return s;
    }
  }
  QuantizeResult result;
  Errors errors;
  while (true) {
    result.spec = BuildSpec(base, convs.precision, ranges.input, ranges.output, weights);
    Result<std::shared_ptr<const Model>> quantised = Load(result.spec, "the quantised model");
    if (!quantised.ok()) return quantised.status();
    Result<Errors> measured = calibrator.Measure(*quantised);
    if (!measured.ok()) return measured.status();
    errors = std::move(measured).value();
    const bool max = options.accuracy_metric == AccuracyMetric::kMax;
    const double error = max ? errors.output_max_rel : errors.output_rms_rel;
    if (options.mode == QuantizeMode::kInt8 || error <= options.accuracy_budget ||
        std::none_of(convs.precision.begin(), convs.precision.end(), Reduced)) {
      break;
    }
    result.auto_steps.push_back(RaiseWorstLayer(errors, options, convs.names, convs.precision));
  }
  result.calibration = DescribeCalibration(*method, options, data, ranges.group, convs, errors);
  if (std::any_of(convs.precision.begin(), convs.precision.end(), Reduced)) {
    result.spec.calibration = result.calibration;
  }
  return result;
}

}  // namespace sfrt::exporter
