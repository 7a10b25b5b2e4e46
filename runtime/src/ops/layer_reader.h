// What a layer kind's parse function reads the stored layer through (ops/layer_op.h): the stored
// op, the layers before it, and the checks every kind shares, each failing with the model's label
// and the layer's name ("model.sfrt: layer 3 'conv2': stride is 0x1; ...").
#pragma once

#include <cstdint>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "sfrt/model.h"
#include "sfrt/status.h"
#include "sfrt_model_generated.h"

namespace sfrt::ops {

namespace schema = ::sfrt::schema;

// Where weight tensors go as they are read: the file's bytes (for the alignment rule), the running
// CRC-32C of all weights, and the fp32 copies of fp16 tensors.
struct WeightStore {
  const uint8_t* file = nullptr;
  bool verify_checksum = true;
  uint32_t crc = 0;
  bool saw_fp16 = false;
  std::vector<std::vector<float>>* widened = nullptr;
};

class LayerReader {
 public:
  LayerReader(const std::string& label, std::string where, const schema::Layer& stored,
              std::span<const LayerDesc> earlier, std::span<const int> channels_of,
              int input_channels, WeightStore& weights, ModelMetadata& metadata)
      : label_(label),
        where_(std::move(where)),
        stored_(stored),
        earlier_(earlier),
        channels_of_(channels_of),
        input_channels_(input_channels),
        weights_(weights),
        metadata_(metadata) {}

  const schema::Layer& stored() const { return stored_; }
  // The layers before this one (what layer.inputs index).
  std::span<const LayerDesc> earlier() const { return earlier_; }
  // The channels of tensor t (kModelInput or an earlier layer).
  int ChannelsRead(int t) const {
    return t == kModelInput ? input_channels_ : channels_of_[static_cast<size_t>(t)];
  }
  // Reduced precisions met, for ModelMetadata.
  void NoteInt8() { metadata_.has_int8 = true; }
  void NoteBf16() { metadata_.has_bf16 = true; }

  // "label: layer i 'name': what".
  Status Fail(const std::string& what) const;
  // How many inputs `op` ("a Conv2D") reads: [least, most].
  Status CheckArity(const LayerDesc& layer, const char* op, int least, int most) const;
  // A convolution's channels: in_channels as its input has them, out_channels in range.
  Status CheckChannels(int in_channels, int input_has, int out_channels) const;
  // A kernel's or window's sides and strides; `what` names it ("kernel", "window").
  Status CheckWindow(const char* what, int kh, int kw, int sh, int sw) const;
  // Dilations (schema 1.8): in range, and 1 unless stored as the op's V2 member (`v2`).
  Status CheckDilation(int dh, int dw, bool v2, const char* op) const;
  // Pads each at least 0 and below the kernel's (dilated) side.
  Status CheckPadsBelowKernel(const Padding& pads, int kh, int kw) const;
  // The activation as stored; Elu, Sigmoid, Tanh and Clip only when `all_kinds`.
  Status TakeActivation(schema::Activation stored, float slope, Activation* activation,
                        float* leaky_slope, bool all_kinds = false) const;
  Status TakePaddingRule(schema::PaddingRule stored, PaddingRule* rule) const;
  // Checks one weight tensor (shape, dtype, byte count, 64-byte alignment), adds it to the
  // weights' CRC and returns float32 data for it (in place, or widened from fp16), or, for an
  // int8 tensor (allowed only where int8_dst is given), its bytes in place.
  Status TakeTensor(const schema::Tensor* t, const char* field, std::initializer_list<int> shape,
                    const float** dst, const int8_t** int8_dst = nullptr);

 private:
  const std::string& label_;
  std::string where_;
  const schema::Layer& stored_;
  std::span<const LayerDesc> earlier_;
  std::span<const int> channels_of_;
  int input_channels_;
  WeightStore& weights_;
  ModelMetadata& metadata_;
};

}  // namespace sfrt::ops
