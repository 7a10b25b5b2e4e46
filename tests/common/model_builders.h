// Helpers that turn exporter ModelSpecs into loaded runtime Models for tests.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"

namespace sfrt::testing {

inline std::vector<uint8_t> SerializeOrDie(const exporter::ModelSpec& spec) {
  auto bytes = exporter::SerializeModel(spec);
  EXPECT_TRUE(bytes.ok()) << bytes.message();
  return bytes.ok() ? std::move(bytes).value() : std::vector<uint8_t>{};
}

inline std::shared_ptr<const Model> LoadOrDie(const exporter::ModelSpec& spec) {
  const std::vector<uint8_t> bytes = SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy);
  EXPECT_TRUE(model.ok()) << model.message();
  return model.ok() ? model.value() : nullptr;
}

}  // namespace sfrt::testing
