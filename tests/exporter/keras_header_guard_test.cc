// The Keras importer against damaged object headers (fuzz_keras_import out-of-memory findings):
// libhdf5 1.10.8 allocates an object-header chunk with the length the file gives before checking
// it against the end of the file (4 GB for a flipped byte), so the importer checks each header
// first (exporter/src/hdf5_header_guard.h): the root group's before H5Fopen, every other object's
// before it is opened or looked through. Files: the two fuzz reproducers and variants of the
// committed valid Keras file tests/fuzz/regression/keras_import/keras_seq_67x121.h5, each with
// one field of an object header changed here.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "hdf5_header_guard.h"
#include "keras_crafted_file.h"
#include "message_text.h"
#include "sfrt/exporter/keras_importer.h"

namespace sfrt::exporter {
namespace {

using testing::ExpectRejectedBothWays;
using testing::ReadFile;
using testing::WriteFile;
const std::string kCorpus = testing::kKerasCorpus;
const std::string kValid = kCorpus + "keras_seq_67x121.h5";

uint64_t GetLe(const std::string& s, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(s[at + i]);
  return v;
}

void PutLe(std::string* s, size_t at, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) (*s)[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
}

// The valid file's facts, found rather than assumed: superblock version 0 with 8-byte addresses
// at byte 0; the root group's version-1 object header at address 96, whose chunk 0 holds one
// continuation message (type 0x10) naming chunk 1.
struct ValidFile {
  std::string bytes;
  size_t root = 0;          // root group object header
  size_t continuation = 0;  // offset of the continuation message's data (address, length)
  uint64_t chunk1 = 0;      // chunk 1's address and length
  uint64_t chunk1_length = 0;
};

ValidFile LoadValid() {
  ValidFile v;
  v.bytes = ReadFile(kValid);
  EXPECT_GE(v.bytes.size(), 200u);
  if (v.bytes.size() < 200) return v;
  EXPECT_EQ(v.bytes[8], 0) << "superblock version";
  EXPECT_EQ(v.bytes[13], 8) << "size of offsets";
  EXPECT_EQ(v.bytes[14], 8) << "size of lengths";
  v.root = GetLe(v.bytes, 24 + 5 * 8, 8);  // root symbol table entry's object header address
  EXPECT_EQ(v.root, 96u);
  EXPECT_EQ(v.bytes[v.root], 1) << "object header version";
  const size_t chunk0 = GetLe(v.bytes, v.root + 8, 4);
  for (size_t at = v.root + 16; at + 8 <= v.root + 16 + chunk0;
       at += 8 + GetLe(v.bytes, at + 2, 2)) {
    if (GetLe(v.bytes, at, 2) == 0x10) {
      v.continuation = at + 8;
      break;
    }
  }
  EXPECT_NE(v.continuation, 0u) << "no continuation message in the root header's chunk 0";
  if (v.continuation == 0) return v;
  v.chunk1 = GetLe(v.bytes, v.continuation, 8);
  v.chunk1_length = GetLe(v.bytes, v.continuation + 8, 8);
  EXPECT_LT(v.chunk1 + v.chunk1_length, v.bytes.size());
  return v;
}

// Both ways of importing `bytes` fail with one line that names the file and contains each of
// `expected`, before libhdf5 reports anything itself.
void ExpectRejected(const std::string& bytes, const std::string& name,
                    std::initializer_list<std::string> expected) {
  ExpectRejectedBothWays(bytes, name, [&](const std::string& message) {
    for (const std::string& e : expected) EXPECT_NE(message.find(e), std::string::npos) << message;
    EXPECT_EQ(message.find("HDF5:"), std::string::npos) << "libhdf5 got to the header: " << message;
  });
}

// The address libhdf5 gives for the hard link `path` of the valid file.
uint64_t LinkAddress(const std::string& path) {
  const hid_t file = H5Fopen(kValid.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0);
  H5L_info_t info{};
  const herr_t got = H5Lget_info(file, path.c_str(), &info, H5P_DEFAULT);
  H5Fclose(file);
  EXPECT_GE(got, 0) << path;
  EXPECT_EQ(info.type, H5L_TYPE_HARD) << path;
  return got >= 0 ? info.u.address : 0;
}

TEST(KerasHeaderGuard, ValidFileStillImportsFromMemoryAndFromItsPath) {
  const ValidFile v = LoadValid();
  auto in_memory = ImportKerasH5FromMemory(v.bytes, "valid.h5");
  ASSERT_TRUE(in_memory.ok()) << in_memory.message();
  auto from_file = ImportKerasH5(kValid);
  ASSERT_TRUE(from_file.ok()) << from_file.message();
  EXPECT_FALSE(in_memory->spec.layers.empty());
}

TEST(KerasHeaderGuard, FuzzReproducerWithA4GbRootContinuationLengthIsRejected) {
  // The root group's continuation length 504 became 0xF40001F8.
  ExpectRejected(ReadFile(kCorpus + "hdf5-continuation-length-4gb-malloc.h5"), "root-4gb.h5",
                 {"object header of the root group at address 96",
                  "a continuation message, gives chunk length 4093641208 at address 800, past the "
                  "end of the file (59417 bytes"});
}

TEST(KerasHeaderGuard, FuzzReproducerWithA4GbModelWeightsContinuationLengthIsRejected) {
  ExpectRejected(ReadFile(kCorpus + "hdf5-continuation-length-4gb-malloc-2.h5"),
                 "model-weights-4gb.h5",
                 {"object header of 'model_weights' at address",
                  "a continuation message, gives chunk length 4294967904 at address 12840, past "
                  "the end of the file (419239 bytes"});
}

TEST(KerasHeaderGuard, ContinuationLengthPastTheEndOfTheFileIsRejected) {
  ValidFile v = LoadValid();
  const uint64_t length = v.bytes.size() - v.chunk1 + 1;  // one byte too long
  PutLe(&v.bytes, v.continuation + 8, length, 8);
  ExpectRejected(v.bytes, "length.h5",
                 {"object header of the root group at address 96: message 0 (type 16) of chunk 0",
                  "gives chunk length " + std::to_string(length) + " at address " +
                      std::to_string(v.chunk1) + ", past the end of the file"});
}

TEST(KerasHeaderGuard, ContinuationAddressPastTheEndOfTheFileIsRejected) {
  ValidFile v = LoadValid();
  PutLe(&v.bytes, v.continuation, uint64_t{1} << 40, 8);
  ExpectRejected(v.bytes, "address.h5",
                 {"object header of the root group",
                  "gives chunk address 1099511627776, past the end of the file"});
}

TEST(KerasHeaderGuard, ContinuationLoopIsRejected) {
  // The last message of chunk 1 (an attribute) becomes a continuation back to chunk 1.
  ValidFile v = LoadValid();
  size_t last = v.chunk1;
  for (size_t at = v.chunk1; at + 8 <= v.chunk1 + v.chunk1_length;
       at += 8 + GetLe(v.bytes, at + 2, 2)) {
    last = at;
  }
  ASSERT_GE(GetLe(v.bytes, last + 2, 2), 16u);
  PutLe(&v.bytes, last, 0x10, 2);
  PutLe(&v.bytes, last + 8, v.chunk1, 8);
  PutLe(&v.bytes, last + 16, v.chunk1_length, 8);
  ExpectRejected(v.bytes, "loop.h5",
                 {"object header of the root group", "continuation chunk 2 is at address " +
                                                         std::to_string(v.chunk1) +
                                                         ", a chunk already read (a loop)"});
}

TEST(KerasHeaderGuard, DatasetHeaderWithAHugeChunkZeroIsRejectedBeforeItIsOpened) {
  // A weight dataset deep in model_weights: its version-1 prefix's chunk-0 size (4 bytes at +8).
  ValidFile v = LoadValid();
  const hid_t file = H5Fopen(kValid.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  // The first layer group with weights and its first weight, as the importer will read them.
  std::string dataset;
  H5Ovisit(
      file, H5_INDEX_NAME, H5_ITER_NATIVE,
      [](hid_t, const char* name, const H5O_info_t* info, void* out) -> herr_t {
        const std::string n = name;
        if (info->type == H5O_TYPE_DATASET && n.rfind("model_weights/", 0) == 0) {
          *static_cast<std::string*>(out) = n;
          return 1;
        }
        return 0;
      },
      &dataset);
  H5Fclose(file);
  ASSERT_FALSE(dataset.empty()) << "no dataset under model_weights";
  const uint64_t address = LinkAddress(dataset);
  ASSERT_EQ(v.bytes[address], 1) << "object header version";
  PutLe(&v.bytes, address + 8, 0xF00001F8, 4);
  ExpectRejected(v.bytes, "dataset.h5",
                 {"object header of '" + dataset + "' at address " + std::to_string(address),
                  "chunk 0 size 4026532344 runs past the end of the file"});
}

// Every object of the file at `path` that libhdf5 finds (name, header address).
std::vector<std::pair<std::string, uint64_t>> Objects(const std::string& path) {
  std::vector<std::pair<std::string, uint64_t>> objects;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0) << path;
  H5Ovisit(
      file, H5_INDEX_NAME, H5_ITER_NATIVE,
      [](hid_t, const char* name, const H5O_info_t* info, void* data) -> herr_t {
        static_cast<std::vector<std::pair<std::string, uint64_t>>*>(data)->emplace_back(name,
                                                                                        info->addr);
        return 0;
      },
      &objects);
  H5Fclose(file);
  return objects;
}

// The guard's verdicts on the root and `objects` of the file image `bytes` ("" when all pass).
std::string CheckAll(const std::string& bytes,
                     const std::vector<std::pair<std::string, uint64_t>>& objects) {
  hdf5::HeaderGuard guard{std::string_view(bytes)};
  std::string errors;
  if (Status root = guard.CheckRoot(); !root.ok()) errors += root.message() + "; ";
  for (const auto& [name, address] : objects) {
    if (Status s = guard.CheckObject(address, Quote(name)); !s.ok()) errors += s.message() + "; ";
  }
  return errors;
}

TEST(KerasHeaderGuard, GuardAcceptsEveryObjectOfTheValidFile) {
  const auto objects = Objects(kValid);
  EXPECT_GT(objects.size(), 3u);
  EXPECT_EQ(CheckAll(ReadFile(kValid), objects), "");
}

// A file in the newest format libhdf5 1.10 writes (superblock 3, "OHDR" version-2 headers with
// times, attribute phase fields and creation order, "OCHK" continuation chunks from attributes
// added after the header was written): the guard finds nothing wrong with any object.
TEST(KerasHeaderGuard, GuardAcceptsEveryObjectOfAVersion2File) {
  const std::string path = ::testing::TempDir() + "/header-guard-v2.h5";
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  ASSERT_GE(H5Pset_libver_bounds(fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST), 0);
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  ASSERT_GE(file, 0);
  const hid_t gcpl = H5Pcreate(H5P_GROUP_CREATE);
  ASSERT_GE(H5Pset_attr_creation_order(gcpl, H5P_CRT_ORDER_TRACKED), 0);
  ASSERT_GE(H5Pset_attr_phase_change(gcpl, 40, 30), 0);
  const hid_t group = H5Gcreate2(file, "model_weights", H5P_DEFAULT, gcpl, H5P_DEFAULT);
  ASSERT_GE(group, 0);
  const hsize_t dims[2] = {3, 5};
  const hid_t space = H5Screate_simple(2, dims, nullptr);
  const hid_t scalar = H5Screate(H5S_SCALAR);
  const float values[15] = {};
  for (int i = 0; i < 4; ++i) {
    const std::string name = "w" + std::to_string(i);
    const hid_t ds = H5Dcreate2(group, name.c_str(), H5T_IEEE_F32LE, space, H5P_DEFAULT,
                                H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
    H5Dclose(ds);
    // Attributes added one by one to the group and the root grow their headers into new chunks.
    for (hid_t obj : {group, file}) {
      for (int a = 0; a < 8; ++a) {
        const std::string attr = name + "_attribute_" + std::to_string(a);
        const hid_t at =
            H5Acreate2(obj, attr.c_str(), H5T_STD_I64LE, scalar, H5P_DEFAULT, H5P_DEFAULT);
        ASSERT_GE(at, 0);
        const int64_t v = a;
        ASSERT_GE(H5Awrite(at, H5T_NATIVE_INT64, &v), 0);
        H5Aclose(at);
      }
    }
  }
  H5Sclose(scalar);
  H5Sclose(space);
  H5Gclose(group);
  H5Pclose(gcpl);
  H5Fclose(file);
  H5Pclose(fapl);
  const std::string bytes = ReadFile(path);
  const auto objects = Objects(path);
  std::filesystem::remove(path);
  ASSERT_EQ(bytes[8], 3) << "superblock version";
  EXPECT_NE(bytes.find("OHDR"), std::string::npos);
  const size_t ochk = bytes.find("OCHK");
  ASSERT_NE(ochk, std::string::npos) << "no continuation chunk was written";
  EXPECT_EQ(objects.size(), 6u);  // the root, the group, four datasets
  EXPECT_EQ(CheckAll(bytes, objects), "");

  // The continuation message naming that chunk (type 0x10, size 16, flags, [creation order]
  // before its address), its length made one byte too long: the guard refuses it.
  std::string address(8, '\0');
  PutLe(&address, 0, ochk, 8);
  size_t message = std::string::npos;
  for (size_t at = bytes.find(address); at != std::string::npos; at = bytes.find(address, at + 1)) {
    for (size_t header : {4, 6}) {
      if (at >= header && bytes[at - header] == 0x10 && GetLe(bytes, at - header + 1, 2) == 16) {
        message = at;
      }
    }
  }
  ASSERT_NE(message, std::string::npos) << "no continuation message names the chunk at " << ochk;
  std::string damaged = bytes;
  const uint64_t length = bytes.size() - ochk + 1;
  PutLe(&damaged, message + 8, length, 8);
  EXPECT_NE(CheckAll(damaged, objects)
                .find("a continuation message, gives chunk length " + std::to_string(length) +
                      " at address " + std::to_string(ochk) + ", past the end of the file"),
            std::string::npos);
  // Its signature damaged instead: refused too.
  damaged = bytes;
  damaged[ochk] = 'X';
  EXPECT_NE(CheckAll(damaged, objects)
                .find("continuation chunk 1 at address " + std::to_string(ochk) +
                      " has no OCHK signature"),
            std::string::npos);
}

// H5Fopen loads a version-2 superblock's extension (an object header) before the root group's:
// a damaged chunk-0 size there is refused before libhdf5 opens the file.
TEST(KerasHeaderGuard, DamagedSuperblockExtensionIsRejected) {
  const std::string path = ::testing::TempDir() + "/header-guard-extension.h5";
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  const hid_t fcpl = H5Pcreate(H5P_FILE_CREATE);
  ASSERT_GE(H5Pset_libver_bounds(fapl, H5F_LIBVER_LATEST, H5F_LIBVER_LATEST), 0);
  ASSERT_GE(H5Pset_sym_k(fcpl, 32, 8), 0);  // not the default: stored in the extension
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl, fapl);
  ASSERT_GE(file, 0);
  H5Fclose(file);
  H5Pclose(fcpl);
  H5Pclose(fapl);
  std::string bytes = ReadFile(path);
  std::filesystem::remove(path);
  ASSERT_GE(bytes.size(), 48u);
  ASSERT_EQ(bytes[8], 3) << "superblock version";
  ASSERT_EQ(bytes[9], 8) << "size of offsets";
  const uint64_t extension = GetLe(bytes, 12 + 8, 8);
  ASSERT_LT(extension + 16, bytes.size()) << "no superblock extension was written";
  ASSERT_EQ(bytes.compare(extension, 4, "OHDR"), 0);
  const unsigned flags = static_cast<uint8_t>(bytes[extension + 5]);
  const size_t size_at =
      extension + 6 + ((flags & 0x20) != 0 ? 16 : 0) + ((flags & 0x10) != 0 ? 4 : 0);
  const int width = 1 << (flags & 3);
  ASSERT_GE(width, 1);
  auto valid = ImportKerasH5FromMemory(bytes, "extension.h5");
  ASSERT_FALSE(valid.ok());  // not a Keras file, but libhdf5 opened it
  EXPECT_NE(valid.message().find("no attribute 'layer_names'"), std::string::npos)
      << valid.message();
  const uint64_t huge = width == 1 ? 0xFF : 0xFFF0;
  PutLe(&bytes, size_at, huge, width);
  ExpectRejected(
      bytes, "extension.h5",
      {"object header of the superblock extension at address " + std::to_string(extension),
       "chunk 0 size " + std::to_string(huge) + " runs past the end of the file"});
}

// fuzz_keras_import (ASan heap-buffer-overflow in libhdf5's H5Aexists -> H5O__msg_iterate_real):
// conv1's attribute weight_names claims 3 fixed-length strings of 14 bytes in a message with
// room for 32; libhdf5 copies 42 bytes from the end of the header chunk.
TEST(KerasHeaderGuard, FuzzReproducerWithAttributeDataPastItsMessageIsRejected) {
  ExpectRejected(ReadFile(kCorpus + "hdf5-attribute-data-past-its-message.h5"), "attr-data.h5",
                 {"object header of 'model_weights/conv1' at address 20168: message 1 (type 12) "
                  "of chunk 1, an attribute message, holds 3 elements of 14 bytes in 32 bytes"});
}

TEST(KerasHeaderGuard, AttributeNameLongerThanItsMessageIsRejected) {
  // The first attribute message (type 0x0C) of the root group's chunk 1: name size made 200.
  ValidFile v = LoadValid();
  size_t attribute = 0;
  for (size_t at = v.chunk1; at + 8 <= v.chunk1 + v.chunk1_length;
       at += 8 + GetLe(v.bytes, at + 2, 2)) {
    if (GetLe(v.bytes, at, 2) == 0x0C) {
      attribute = at;
      break;
    }
  }
  ASSERT_NE(attribute, 0u) << "no attribute message in the root group's chunk 1";
  const uint64_t size = GetLe(v.bytes, attribute + 2, 2);
  ASSERT_LT(size, 200u);
  PutLe(&v.bytes, attribute + 8 + 2, 200, 2);
  ExpectRejected(v.bytes, "attr-name.h5",
                 {"object header of the root group at address 96: message",
                  "an attribute message, has name size 200",
                  "more than its " + std::to_string(size) + " bytes"});
}

// fuzz_keras_import (ASan heap-buffer-overflow in libhdf5's H5Aread -> H5A__read -> memcpy): the
// root attribute model_config's variable-length string datatype says 9 bytes per element;
// libhdf5 allocates the data at that size, then copies a 16-byte heap ID out of it.
TEST(KerasHeaderGuard, FuzzReproducerWithAVariableLengthStringOfNineBytesIsRejected) {
  ExpectRejected(ReadFile(kCorpus + "vlen-string-size-not-a-heap-id.h5"), "vlen-size.h5",
                 {"object header of the root group at address 96: message",
                  "an attribute message, has a variable-length datatype of 9 bytes per element; a "
                  "heap ID takes 16"});
}

// fuzz_keras_import (libFuzzer out-of-memory, 1.7 GB in libhdf5's H5T__conv_vlen under
// H5Aread): model_config's variable-length string says its characters are 524289 bytes each.
TEST(KerasHeaderGuard, FuzzReproducerWithHalfMegabyteCharactersIsRejected) {
  ExpectRejected(ReadFile(kCorpus + "oom-vlen-string-half-megabyte-characters.h5"), "vlen-item.h5",
                 {"object header of the root group at address 96: message",
                  "an attribute message, has a variable-length datatype of 524289-byte items; "
                  "strings have 1-byte characters"});
}

TEST(KerasHeaderGuard, VariableLengthStringWithAHeapIdLargerThanSixteenBytesIsRejected) {
  // model_config's datatype (version 1 attribute message: name padded to 8 bytes) made 24 bytes.
  ValidFile v = LoadValid();
  const size_t name = v.bytes.find("model_config");
  ASSERT_NE(name, std::string::npos);
  const size_t datatype = name + 16;
  ASSERT_EQ(static_cast<uint8_t>(v.bytes[datatype]) & 0x0F, 9) << "not a variable-length type";
  ASSERT_EQ(GetLe(v.bytes, datatype + 4, 4), 16u);
  PutLe(&v.bytes, datatype + 4, 24, 4);
  ExpectRejected(v.bytes, "vlen-24.h5",
                 {"an attribute message, has a variable-length datatype of 24 bytes per element"});
}

// A soft link would make libhdf5 load a header the importer never got an address for (H5Lget_info
// does not resolve it): refused; Keras writes hard links only.
TEST(KerasHeaderGuard, SoftLinkOnTheImportersPathIsRejected) {
  const std::string path = ::testing::TempDir() + "/header-guard-soft.h5";
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t group = H5Gcreate2(file, "weights", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(group, 0);
  H5Gclose(group);
  ASSERT_GE(H5Lcreate_soft("/weights", file, "model_weights", H5P_DEFAULT, H5P_DEFAULT), 0);
  H5Fclose(file);
  const std::string bytes = ReadFile(path);
  std::filesystem::remove(path);
  ExpectRejected(bytes, "soft.h5", {"'model_weights' is a soft or external link (link type 1)"});
}

// fuzz_keras_import (the target's own abort: an accepted model the loader refused): a
// ZeroPadding2D of [[1, 1], [2, 5]] folded into the next 3x3 Conv2D gave pads.right 5.
TEST(KerasImportRegression, ZeroPaddingWiderThanTheKernelIsRejected) {
  ExpectRejected(ReadFile(kCorpus + "zero-padding-wider-than-kernel-abort.h5"), "pad.h5",
                 {"layer 'conv2d_2' (Conv2D): follows ZeroPadding2D 'zero_padding2d_1' whose "
                  "padding gives it 5 on the right; a 3x3 kernel takes at most 2"});
}

// The first 4-D dataset (a Conv2D kernel) of the valid file, by path from the file root.
herr_t FindKernel(hid_t obj, const char* name, const H5O_info_t* info, void* out) {
  if (info->type != H5O_TYPE_DATASET) return 0;
  const hid_t ds = H5Dopen2(obj, name, H5P_DEFAULT);
  const hid_t space = H5Dget_space(ds);
  const int rank = H5Sget_simple_extent_ndims(space);
  H5Sclose(space);
  H5Dclose(ds);
  if (rank != 4) return 0;
  *static_cast<std::string*>(out) = name;
  return 1;
}

// A copy of the valid file whose first Conv2D kernel is made again with the same shape by
// `make(file, path, space)` (which returns the new dataset), then imported both ways.
std::string RemakeFirstKernel(const std::string& name,
                              const std::function<hid_t(hid_t, const char*, hid_t)>& make) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::filesystem::copy_file(kValid, path, std::filesystem::copy_options::overwrite_existing);
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  EXPECT_GE(file, 0);
  std::string kernel;
  H5Ovisit(file, H5_INDEX_NAME, H5_ITER_NATIVE, FindKernel, &kernel);
  EXPECT_FALSE(kernel.empty()) << "no 4-D dataset in " << kValid;
  const hid_t old = H5Dopen2(file, kernel.c_str(), H5P_DEFAULT);
  const hid_t space = H5Dget_space(old);
  std::vector<float> values(static_cast<size_t>(H5Sget_simple_extent_npoints(space)));
  EXPECT_GE(H5Dread(old, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(old);
  EXPECT_GE(H5Ldelete(file, kernel.c_str(), H5P_DEFAULT), 0);
  const hid_t made = make(file, kernel.c_str(), space);
  EXPECT_GE(made, 0);
  if (made >= 0 && H5Dget_storage_size(made) == 0 && name.find("unwritten") == std::string::npos) {
    EXPECT_GE(H5Dwrite(made, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  }
  H5Dclose(made);
  H5Sclose(space);
  H5Fclose(file);
  const std::string bytes = ReadFile(path);
  std::filesystem::remove(path);
  return bytes;
}

// A dataset whose values were never written reads as its fill value, so a damaged dataspace could
// make the importer allocate up to 4 GB for a file of kilobytes (found reading the importer while
// looking for the cause of a fuzz_keras_import out-of-memory whose input libFuzzer did not keep).
// A kernel made with its shape but no data is refused.
TEST(KerasStoredSize, DatasetWhoseValuesWereNeverWrittenIsRejected) {
  const std::string bytes = RemakeFirstKernel("unwritten.h5", [](hid_t f, const char* p, hid_t s) {
    return H5Dcreate2(f, p, H5T_IEEE_F32LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  });
  ExpectRejected(bytes, "unwritten.h5",
                 {"values of 4 bytes", "but stores 0 (values never written: a damaged file)"});
}

// Compressed weights (chunked, deflate) are not what Keras writes, but they are a sound file: they
// still import, to the same weights.
TEST(KerasStoredSize, CompressedKernelStillImportsToTheSameWeights) {
  const std::string bytes = RemakeFirstKernel("deflate.h5", [](hid_t f, const char* p, hid_t s) {
    hsize_t dims[4] = {};
    H5Sget_simple_extent_dims(s, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 4, dims);
    H5Pset_deflate(dcpl, 6);
    const hid_t ds = H5Dcreate2(f, p, H5T_IEEE_F32LE, s, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    H5Pclose(dcpl);
    return ds;
  });
  auto remade = ImportKerasH5FromMemory(bytes, "deflate.h5");
  ASSERT_TRUE(remade.ok()) << remade.message();
  auto valid = ImportKerasH5(kValid);
  ASSERT_TRUE(valid.ok()) << valid.message();
  ASSERT_EQ(remade->spec.layers.size(), valid->spec.layers.size());
  int convs = 0;
  for (size_t i = 0; i < valid->spec.layers.size(); ++i) {
    const auto* want = std::get_if<ConvSpec>(&valid->spec.layers[i]);
    const auto* got = std::get_if<ConvSpec>(&remade->spec.layers[i]);
    ASSERT_EQ(want == nullptr, got == nullptr) << "layer " << i;
    if (want == nullptr) continue;
    ++convs;
    EXPECT_EQ(got->weights_hwio, want->weights_hwio) << "layer " << i;
    EXPECT_EQ(got->bias, want->bias) << "layer " << i;
  }
  EXPECT_GT(convs, 0);
}

}  // namespace
}  // namespace sfrt::exporter
