// The Keras importer against damaged global-heap references (issue #8): libhdf5 1.10.8 follows a
// variable-length string's heap ID without bounds checks (SIGSEGV in H5HG_read), so the importer
// checks each one first (exporter/src/hdf5_vlen_guard.h). Files: the fuzz reproducer and
// variants of the committed valid Keras file tests/fuzz/regression/keras_import/
// keras_seq_67x121.h5, each with one field of model_config's heap ID or of its heap collection
// changed here. Without the check most of them crash the test process.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "hdf5_vlen_guard.h"
#include "keras_crafted_file.h"
#include "sfrt/exporter/keras_importer.h"

namespace sfrt::exporter {
namespace {

using testing::ExpectRejectedBothWays;
using testing::ReadFile;
using testing::WriteFile;
const std::string kCorpus = testing::kKerasCorpus;

void PutLe(std::string* s, size_t at, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) (*s)[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
}

// The valid file's facts, found rather than assumed: model_config is object 1 (3273 bytes) of
// the collection at address 2048; its heap ID is "length 3273, address 2048, index 1".
struct ValidFile {
  std::string bytes;
  size_t heap_id = 0;     // offset of model_config's heap ID (length field)
  size_t collection = 0;  // offset of the GCOL collection
};

ValidFile LoadValid() {
  ValidFile v;
  v.bytes = ReadFile(kCorpus + "keras_seq_67x121.h5");
  std::string id(16, '\0');
  PutLe(&id, 0, 3273, 4);
  PutLe(&id, 4, 2048, 8);
  PutLe(&id, 12, 1, 4);
  v.heap_id = v.bytes.find(id);
  v.collection = v.bytes.find("GCOL");
  EXPECT_NE(v.heap_id, std::string::npos) << "model_config's heap ID not found";
  EXPECT_EQ(v.collection, 2048u);
  return v;
}

// Both ways of importing `bytes` fail with one line that names the file and the model_config
// attribute and contains `expected`.
void ExpectRejected(const std::string& bytes, const std::string& name,
                    const std::string& expected) {
  ExpectRejectedBothWays(bytes, name, [&](const std::string& message) {
    EXPECT_NE(message.find("attribute 'model_config' of the file root"), std::string::npos)
        << message;
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  });
}

TEST(KerasHeapGuard, ValidFileStillImportsFromMemoryAndFromItsPath) {
  const ValidFile v = LoadValid();
  auto in_memory = ImportKerasH5FromMemory(v.bytes, "valid.h5");
  ASSERT_TRUE(in_memory.ok()) << in_memory.message();
  auto from_file = ImportKerasH5(kCorpus + "keras_seq_67x121.h5");
  ASSERT_TRUE(from_file.ok()) << from_file.message();
  EXPECT_FALSE(in_memory->spec.layers.empty());
  EXPECT_EQ(in_memory->spec.layers.size(), from_file->spec.layers.size());
}

TEST(KerasHeapGuard, FuzzReproducerWithHeapIndexBeyondTheCollectionIsRejected) {
  // Byte 1015 of the reproducer turned model_config's object index 1 into 0x64000001.
  const std::string bytes = ReadFile(kCorpus + "hdf5-global-heap-read-segv.h5");
  ExpectRejected(bytes, "segv.h5",
                 "variable-length string 0 refers to object 1677721601 of the global heap "
                 "collection at address 2048, which does not exist");
}

TEST(KerasHeapGuard, HeapIndexOfAnEmptySlotIsRejected) {
  ValidFile v = LoadValid();
  PutLe(&v.bytes, v.heap_id + 12, 2, 4);  // slot 2 exists in libhdf5's table, holds nothing
  ExpectRejected(v.bytes, "slot2.h5",
                 "object 2 of the global heap collection at address 2048, "
                 "which does not exist (the collection holds 1 objects");
}

TEST(KerasHeapGuard, HeapIndexZeroTheFreeSpaceIsRejected) {
  ValidFile v = LoadValid();
  PutLe(&v.bytes, v.heap_id + 12, 0, 4);
  ExpectRejected(v.bytes, "index0.h5", "object 0 of the global heap collection");
}

TEST(KerasHeapGuard, LengthDifferentFromTheHeapObjectIsRejected) {
  ValidFile v = LoadValid();
  PutLe(&v.bytes, v.heap_id, 40000, 4);
  ExpectRejected(v.bytes, "length.h5",
                 "has length 40000 but object 1 of the global heap "
                 "collection at address 2048 holds 3273 bytes");
}

TEST(KerasHeapGuard, CollectionAddressOutsideTheFileOrNotACollectionIsRejected) {
  ValidFile v = LoadValid();
  std::string outside = v.bytes;
  PutLe(&outside, v.heap_id + 4, uint64_t{1} << 40, 8);
  ExpectRejected(outside, "outside.h5", "is outside the file");
  std::string elsewhere = v.bytes;
  PutLe(&elsewhere, v.heap_id + 4, 1024, 8);
  ExpectRejected(elsewhere, "elsewhere.h5", "has no GCOL version 1 signature");
}

TEST(KerasHeapGuard, CollectionWithAnObjectPastItsEndIsRejected) {
  ValidFile v = LoadValid();
  std::string big = v.bytes;  // object 1's size field: collection + 16 (header) + 8
  PutLe(&big, v.collection + 24, uint64_t{1} << 62, 8);
  ExpectRejected(big, "object-size.h5", "past its end");
  std::string small = v.bytes;  // the collection's own size, under libhdf5's minimum
  PutLe(&small, v.collection + 8, 64, 8);
  ExpectRejected(small, "collection-size.h5", "declares 64 bytes");
  std::string free0 = v.bytes;  // the free-space object (after object 1) with size 0
  const size_t free_at = v.collection + 16 + 16 + ((3273 + 7) / 8) * 8;
  ASSERT_EQ(free0[free_at], 0);  // index 0
  PutLe(&free0, free_at + 8, 0, 8);
  ExpectRejected(free0, "free-space.h5", "(free space) declares 0 bytes");
}

// While a guard is installed, conversions between memory vlen types (nothing of a file to
// check) still go through libhdf5's own conversion and give its result; after it, too.
TEST(KerasHeapGuard, MemoryToMemoryVlenConversionIsUntouched) {
  auto convert = [] {
    const hid_t src = H5Tvlen_create(H5T_NATIVE_INT);
    const hid_t dst = H5Tvlen_create(H5T_NATIVE_SHORT);
    int values[3] = {7, -2, 300};
    hvl_t buf[1] = {{3, values}};
    const herr_t r = H5Tconvert(src, dst, 1, buf, nullptr, H5P_DEFAULT);
    std::vector<short> out;
    if (r >= 0) {
      const auto* p = static_cast<const short*>(buf[0].p);
      out.assign(p, p + buf[0].len);
      H5free_memory(buf[0].p);
    }
    H5Tclose(src);
    H5Tclose(dst);
    return out;
  };
  const std::vector<short> want = {7, -2, 300};
  {
    const std::string image = ReadFile(kCorpus + "keras_seq_67x121.h5");
    hdf5::VlenGuard guard{std::string_view(image)};
    ASSERT_TRUE(guard.Install().ok());
    EXPECT_EQ(convert(), want);
    EXPECT_EQ(guard.TakeRefusal(), "");
  }
  EXPECT_EQ(hdf5::VlenGuard::Current(), nullptr);
  EXPECT_EQ(convert(), want);
}

}  // namespace
}  // namespace sfrt::exporter
