// How each layer kind is written to the model file: one Write overload per LayerSpec alternative,
// each in its kind's file (writers/<kind>.cc), found by std::visit over the spec's variant
// (SerializeModel). A kind's reading and checking is the runtime's unit
// (runtime/src/ops/<kind>.cc); the writer refuses what that reader would, naming the layer.
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/layer_kinds.h"
#include "sfrt/status.h"
#include "sfrt_model_generated.h"

namespace sfrt::exporter::writers {

namespace fb = ::sfrt::schema;

// The model's builder and its weight tensors: each 64-byte aligned, as float32 or float16 (the
// file's weight type) or int8, and added to the weights' CRC-32C in the order written.
class TensorWriter {
 public:
  explicit TensorWriter(WeightType type) : type_(type) {}
  flatbuffers::Offset<fb::Tensor> AddTensor(const std::vector<float>& values,
                                            std::initializer_list<int> shape);
  // Int8 weights (schema 1.3): the bytes as they are.
  flatbuffers::Offset<fb::Tensor> AddInt8Tensor(const std::vector<int8_t>& values,
                                                std::initializer_list<int> shape);
  flatbuffers::FlatBufferBuilder& builder() { return builder_; }
  uint32_t crc() const { return crc_; }

 private:
  WeightType type_;
  flatbuffers::FlatBufferBuilder builder_{1 << 20};
  uint32_t crc_ = 0;
};

fb::PaddingRule ToSchema(PaddingRule r);
fb::Activation ToSchema(Activation a);
fb::Precision ToSchema(Precision p);

// One layer being written: what its writer reads, and what it gives back.
struct LayerWriting {
  TensorWriter& w;
  int schema_minor = 0;
  std::string where;      // "layer 3 'conv2'"
  std::vector<int> read;  // the channels of each tensor it reads
  size_t inputs_named = 0;
  flatbuffers::Offset<flatbuffers::Vector<flatbuffers::Offset<flatbuffers::String>>> names;
  // Set by the writer:
  flatbuffers::Offset<fb::Layer> layer;
  int channels = 0;  // the output's; the first input's unless the writer sets it

  // "where: <what> schema 1.<minor>; writing 1.<schema_minor>" when the file is older than
  // `minor` (`what` ends in "needs" or "need").
  Status Requires(int minor, const std::string& what) const;
  Status Fail(const std::string& what) const;
  // The Layer table with this op.
  void Emit(const std::string& name, fb::LayerOp op, flatbuffers::Offset<void> table);
};

Status Write(const ConvSpec& spec, LayerWriting& out);
Status Write(const UpsampleSpec& spec, LayerWriting& out);
Status Write(const CropSpec& spec, LayerWriting& out);
Status Write(const ConcatSpec& spec, LayerWriting& out);
Status Write(const AddSpec& spec, LayerWriting& out);
Status Write(const ConvTransposeSpec& spec, LayerWriting& out);
Status Write(const PoolSpec& spec, LayerWriting& out);
Status Write(const ResizeSpec& spec, LayerWriting& out);
Status Write(const ChannelAffineSpec& spec, LayerWriting& out);

// The spec a loaded layer was written from (sfrt files re-exported: sfrt_importer.cc), one per
// kind beside its writer, found through SpecOfLayer's table.
LayerSpec SpecOfLayer(const LayerDesc& layer);
LayerSpec ConvSpecOf(const LayerDesc& layer);
LayerSpec UpsampleSpecOf(const LayerDesc& layer);
LayerSpec CropSpecOf(const LayerDesc& layer);
LayerSpec ConcatSpecOf(const LayerDesc& layer);
LayerSpec AddSpecOf(const LayerDesc& layer);
LayerSpec ConvTransposeSpecOf(const LayerDesc& layer);
LayerSpec PoolSpecOf(const LayerDesc& layer);
LayerSpec ResizeSpecOf(const LayerDesc& layer);
LayerSpec ChannelAffineSpecOf(const LayerDesc& layer);

}  // namespace sfrt::exporter::writers
