// Keeps libhdf5 1.10 from dereferencing a damaged global-heap reference.
//
// Variable-length data (Keras' string attributes: model_config, layer_names, weight_names) is
// stored in the file as "length, heap collection address, object index"; libhdf5 1.10.8 turns it
// into memory inside its vlen conversion (H5T__conv_vlen -> H5HG_read), which checks neither that
// the index names an object of the collection nor that the object fits the stored length (the
// checks are assertions, compiled out of release builds): a crafted index reads outside the
// collection's object table and crashes the process.
//
// While a VlenGuard is installed, every vlen -> vlen conversion in the process goes through a
// soft conversion function registered with H5Tregister. In the installing thread it checks each
// element's raw on-disk form (the very bytes libhdf5 is about to follow) against the heap
// collection it names, parsed here from the file's own bytes, and only then hands the buffer to
// the library's own vlen conversion (found with H5Tfind before registering). A bad reference
// makes the conversion fail (the read returns an error) and Refusal() says why.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::exporter::hdf5 {

class VlenGuard {
 public:
  // Checks against the bytes of an in-memory file image (which must outlive the guard).
  explicit VlenGuard(std::string_view image);
  // Checks against the file at `path`, read on demand.
  explicit VlenGuard(std::string path);
  ~VlenGuard();
  VlenGuard(const VlenGuard&) = delete;
  VlenGuard& operator=(const VlenGuard&) = delete;

  // Registers the checking conversion (process-wide, reference counted) and makes this guard the
  // one the current thread's conversions check against. Call before opening the file.
  Status Install();

  // Why the last conversion was refused ("" when none was), then forgets it.
  std::string TakeRefusal();

  // For the conversion function: the guard installed in this thread, or nullptr.
  static VlenGuard* Current();
  // Checks `nelmts` raw on-disk vlen elements (`stride` bytes apart) whose base type has
  // `base_size` bytes; the element size is `element_size`. Sets the refusal and returns false
  // when one is bad.
  bool CheckElements(const uint8_t* buf, size_t nelmts, size_t stride, size_t element_size,
                     size_t base_size, bool is_string);

 private:
  struct Object {
    uint64_t size = 0;
    bool present = false;
  };
  struct Collection {
    std::string error;            // why the collection is unusable ("" when usable)
    std::vector<Object> objects;  // by index; objects[0] is the free space
  };
  bool ReadBytes(uint64_t offset, size_t size, std::string* out);
  bool LoadSuperblock();
  const Collection& LoadCollection(uint64_t address);
  bool Refuse(std::string why);

  std::string_view image_;
  std::string path_;
  bool from_file_ = false;
  uint64_t file_size_ = 0;
  bool installed_ = false;
  // Superblock facts (once, on the first check).
  bool superblock_read_ = false;
  std::string superblock_error_;
  uint64_t base_ = 0;  // where address 0 is in the file (the superblock's offset)
  unsigned sizeof_addr_ = 0;
  unsigned sizeof_size_ = 0;
  std::map<uint64_t, Collection> collections_;
  std::string refusal_;
};

}  // namespace sfrt::exporter::hdf5
