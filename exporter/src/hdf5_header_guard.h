// Checks HDF5 object headers in a file's bytes before libhdf5 loads them.
//
// libhdf5 1.10.8 allocates each object-header chunk with the length the file gives (the chunk-0
// size in the header prefix, the length in every continuation message) before comparing it with
// the end of the file: a damaged length such as 0xF40001F8 makes it allocate 4 GB (H5C_protect,
// reached from H5Fopen for the root group and from H5Gopen2/H5Dopen2 for any object). A
// HeaderGuard walks an object header the way libhdf5 will (the prefix, every message of every
// chunk, each continuation message's chunk) and refuses it when a chunk does not lie inside the
// file, when there are too many chunks or when continuation messages form a loop. It reads only
// the bytes it needs (at most the file size in all).
#pragma once

#include <cstdint>
#include <fstream>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::exporter::hdf5 {

class HeaderGuard {
 public:
  // Most chunks one object header may have (libhdf5 writes one, or a few after many edits).
  static constexpr int kMaxChunks = 1024;

  // Checks against the bytes of an in-memory file image (which must outlive the guard).
  explicit HeaderGuard(std::string_view image);
  // Checks against the file at `path`, read on demand.
  explicit HeaderGuard(std::string path);

  // Checks the root group's object header (found through the superblock) and the superblock
  // extension's (superblock versions 2 and 3, when there is one). The error names the
  // object, the field and its value (not the file: the caller adds it).
  Status CheckRoot();
  // Checks the object header at `address` (a file address, as H5Lget_info gives it; relative to
  // the superblock). `name` names the object in errors ("'model_weights/conv1'").
  Status CheckObject(uint64_t address, const std::string& name);

 private:
  Status LoadSuperblock();
  bool ReadBytes(uint64_t offset, uint64_t size, std::string* out);
  struct Chunk {
    uint64_t address;
    uint64_t length;
  };
  // Walks the messages of chunk `index`'s message area (`size` bytes at `p`) and appends the
  // chunks its continuation messages name to `queue`, checking they lie inside the file.
  Status WalkMessages(const std::string& where, int index, const uint8_t* p, uint64_t size,
                      int version, bool creation_order, std::vector<Chunk>* queue) const;

  std::string_view image_;
  std::string path_;
  bool from_file_ = false;
  std::ifstream in_;
  uint64_t file_size_ = 0;
  bool superblock_read_ = false;
  Status superblock_ = Status::Ok();
  uint64_t base_ = 0;  // file offset of address 0 (where the superblock is)
  unsigned sizeof_addr_ = 0;
  unsigned sizeof_size_ = 0;
  static constexpr uint64_t kUndefined = ~uint64_t{0};
  uint64_t root_ = 0;                // root group object header address
  uint64_t extension_ = kUndefined;  // superblock extension object header address (v2/v3)
  std::set<uint64_t> checked_;       // object headers found sound
};

}  // namespace sfrt::exporter::hdf5
