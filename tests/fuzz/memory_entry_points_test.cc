// The in-memory importer entry points the fuzz targets use give the same result as the path
// entry points on the same bytes (the committed regression seeds are real exporter inputs).
#include <gtest/gtest.h>
#include <hdf5.h>

#include <fstream>
#include <iterator>
#include <string>

#include "sfrt/exporter/keras_importer.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/onnx_importer.h"

namespace sfrt::exporter {
namespace {

const std::string kRegression = SFRT_SOURCE_DIR "/tests/fuzz/regression/";

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(ImportOnnxFromMemory, MatchesImportOnnxOnTheSameFile) {
  const std::string path = kRegression + "onnx_import/w64_torch.onnx";
  const std::string bytes = ReadAll(path);
  auto from_file = ImportOnnx(path);
  ASSERT_TRUE(from_file.ok()) << from_file.message();
  auto from_memory = ImportOnnxFromMemory(bytes, path);
  ASSERT_TRUE(from_memory.ok()) << from_memory.message();
  EXPECT_EQ(from_memory->producer.source_file, "w64_torch.onnx");
  EXPECT_EQ(from_memory->producer.source_sha256, from_file->producer.source_sha256);
  auto a = SerializeModel(*from_file);
  auto b = SerializeModel(*from_memory);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
}

TEST(ImportOnnxFromMemory, ErrorsNameTheLabel) {
  auto r = ImportOnnxFromMemory("not a protobuf", "camera.onnx");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.message().rfind("camera.onnx: not a valid ONNX file", 0), 0u) << r.message();
}

TEST(ImportKerasH5FromMemory, MatchesImportKerasH5OnTheSameFile) {
  const std::string path = kRegression + "keras_import/keras_seq_67x121.h5";
  const std::string bytes = ReadAll(path);
  auto from_file = ImportKerasH5(path);
  ASSERT_TRUE(from_file.ok()) << from_file.message();
  auto from_memory = ImportKerasH5FromMemory(bytes, path);
  ASSERT_TRUE(from_memory.ok()) << from_memory.message();
  EXPECT_EQ(from_memory->spec.producer.source_sha256, from_file->spec.producer.source_sha256);
  EXPECT_EQ(from_memory->notes, from_file->notes);
  auto a = SerializeModel(from_file->spec);
  auto b = SerializeModel(from_memory->spec);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(*a, *b);
}

TEST(ImportKerasH5FromMemory, RejectsBytesWithoutHdf5Signature) {
  auto r = ImportKerasH5FromMemory(std::string(2048, 'x'), "model.h5");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("model.h5: not an HDF5 file (no HDF5 signature in its 2048 bytes)"),
            std::string::npos)
      << r.message();
}

// Every HDF5 file the importer opens is closed again, whether the import succeeds or fails part
// way (a damaged heap, a missing group): no file and no object inside one stays open, so a
// long-running exporter or a fuzzer does not accumulate handles. H5Fget_obj_count counts the
// identifiers open in this process across all files.
TEST(ImportKerasH5, LeavesNoHdf5FileOrObjectOpen) {
  const std::string dir = kRegression + "keras_import/";
  for (const char* name :
       {"keras_seq_67x121.h5", "leak-vlen-strings-partial-read.h5", "leak-hdf5-internal-2.h5"}) {
    const std::string path = dir + name;
    const std::string bytes = ReadAll(path);
    for (bool in_memory : {false, true}) {
      auto r = in_memory ? ImportKerasH5FromMemory(bytes, path) : ImportKerasH5(path);
      (void)r;
      EXPECT_EQ(H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL), 0)
          << name << (in_memory ? " (in memory)" : " (path)") << ": "
          << H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_FILE) << " files still open";
    }
  }
}

}  // namespace
}  // namespace sfrt::exporter
