// How the guard works and why this way (issue #8):
//
// libhdf5 1.10.8 reads variable-length data with H5T__conv_vlen: for each element it decodes the
// on-disk form (4-byte length, heap collection address, 4-byte object index) and calls
// H5HG_read, which loads the collection and copies heap->obj[index] (begin, size) without
// checking index < nused or that the slot holds an object (assertions only), into a buffer sized
// from the stored length without comparing it with the object's size. The collection loader
// (H5HG__cache_heap_deserialize) likewise trusts each object's size field when stepping to the
// next one. A crafted index or size therefore reads outside libhdf5's own arrays (SIGSEGV).
//
// Reading the attributes' raw bytes ourselves (parsing object headers, attribute messages, dense
// attribute storage) would duplicate much of HDF5 and could disagree with the library about
// which bytes it then follows. A soft conversion function sees exactly those bytes: HDF5 passes
// the buffer of on-disk elements to the vlen conversion before anything follows them. So the
// guard registers one (H5Tregister, soft, vlen -> vlen) that checks every element against the
// collection it names, parsed from the file's bytes with the bounds libhdf5 lacks, and then calls
// the library's own H5T__conv_vlen (its address taken with H5Tfind before registering). It is
// registered only while an import runs (H5Tregister replaces the existing vlen paths,
// H5Tunregister removes every path that uses it), so no path cached by other code bypasses it.
#include "hdf5_vlen_guard.h"

#include <hdf5.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <utility>

namespace sfrt::exporter::hdf5 {
namespace {

constexpr char kConversionName[] = "sfrt_checked_vlen";
// Global heap collection format (HDF5 file format specification, "Global Heap").
constexpr char kCollectionMagic[] = "GCOL";
constexpr uint64_t kMinCollectionSize = 4096;  // H5HG_MINSIZE: libhdf5 never writes less

std::mutex g_mutex;
int g_installs = 0;                   // guards alive (registered while > 0)
H5T_conv_t g_library_vlen = nullptr;  // libhdf5's own vlen -> vlen conversion
thread_local VlenGuard* t_current = nullptr;

uint64_t Align8(uint64_t n) { return (n + 7) & ~uint64_t{7}; }

uint64_t LittleEndian(const uint8_t* p, unsigned bytes) {
  uint64_t v = 0;
  for (unsigned i = bytes; i > 0; --i) v = (v << 8) | p[i - 1];
  return v;
}

herr_t CheckedVlenConversion(hid_t src_id, hid_t dst_id, H5T_cdata_t* cdata, size_t nelmts,
                             size_t buf_stride, size_t bkg_stride, void* buf, void* bkg,
                             hid_t dxpl) {
  VlenGuard* guard = VlenGuard::Current();
  if (cdata != nullptr && cdata->command == H5T_CONV_CONV && guard != nullptr && nelmts > 0 &&
      buf != nullptr) {
    const H5T_class_t cls = H5Tget_class(src_id);
    const size_t element_size = H5Tget_size(src_id);
    size_t base_size = 1;  // a variable-length string's characters
    // Whether the source is the memory form (a char* or an hvl_t, nothing of the file to follow).
    // A string's memory form is a pointer, shorter than any on-disk form (4 + address + 4
    // bytes); an hvl_t can have the on-disk size, so a sequence is compared with the memory
    // type of the same base (H5Tequal tells memory and file location apart).
    bool memory_form = cls == H5T_STRING && element_size == sizeof(char*);
    if (cls == H5T_VLEN) {
      const hid_t super = H5Tget_super(src_id);
      base_size = super >= 0 ? H5Tget_size(super) : 0;
      const hid_t memory = super >= 0 ? H5Tvlen_create(super) : H5I_INVALID_HID;
      memory_form = memory >= 0 && H5Tequal(src_id, memory) > 0;
      if (memory >= 0) H5Tclose(memory);
      if (super >= 0) H5Tclose(super);
    }
    if (!memory_form && (element_size == 0 || base_size == 0 ||
                         !guard->CheckElements(static_cast<const uint8_t*>(buf), nelmts,
                                               buf_stride != 0 ? buf_stride : element_size,
                                               element_size, base_size, cls == H5T_STRING))) {
      return -1;
    }
  }
  // H5T_CONV_INIT and H5T_CONV_FREE, other threads and checked data: the library's conversion.
  return g_library_vlen(src_id, dst_id, cdata, nelmts, buf_stride, bkg_stride, buf, bkg, dxpl);
}

// libhdf5's vlen conversion: H5Tfind on two memory vlen types that differ (so it is not the
// no-op path). Called before the checked conversion is first registered.
H5T_conv_t FindLibraryVlenConversion() {
  const hid_t a = H5Tvlen_create(H5T_NATIVE_INT);
  const hid_t b = H5Tvlen_create(H5T_NATIVE_SHORT);
  H5T_conv_t found = nullptr;
  if (a >= 0 && b >= 0) {
    H5T_cdata_t* cdata = nullptr;
    found = H5Tfind(a, b, &cdata);
  }
  if (a >= 0) H5Tclose(a);
  if (b >= 0) H5Tclose(b);
  return found;
}

}  // namespace

VlenGuard::VlenGuard(std::string_view image) : image_(image), file_size_(image.size()) {}

VlenGuard::VlenGuard(std::string path) : path_(std::move(path)), from_file_(true) {}

VlenGuard::~VlenGuard() {
  if (!installed_) return;
  t_current = nullptr;
  std::lock_guard<std::mutex> lock(g_mutex);
  if (--g_installs == 0) {
    H5Tunregister(H5T_PERS_SOFT, kConversionName, H5I_INVALID_HID, H5I_INVALID_HID,
                  CheckedVlenConversion);
    H5Eclear2(H5E_DEFAULT);
  }
}

Status VlenGuard::Install() {
  if (installed_) return Status::Ok();
  if (t_current != nullptr) return Status::Error("an HDF5 vlen guard is already installed");
  std::lock_guard<std::mutex> lock(g_mutex);
  if (g_library_vlen == nullptr) {
    g_library_vlen = FindLibraryVlenConversion();
    if (g_library_vlen == nullptr) {
      H5Eclear2(H5E_DEFAULT);
      return Status::Error("cannot find libhdf5's variable-length conversion (H5Tfind)");
    }
  }
  if (g_installs == 0) {
    const hid_t vlen = H5Tvlen_create(H5T_NATIVE_UCHAR);
    const herr_t registered =
        vlen < 0 ? -1
                 : H5Tregister(H5T_PERS_SOFT, kConversionName, vlen, vlen, CheckedVlenConversion);
    if (vlen >= 0) H5Tclose(vlen);
    if (registered < 0) {
      H5Eclear2(H5E_DEFAULT);
      return Status::Error("cannot register the checked variable-length conversion (H5Tregister)");
    }
  }
  ++g_installs;
  installed_ = true;
  t_current = this;
  return Status::Ok();
}

VlenGuard* VlenGuard::Current() { return t_current; }

std::string VlenGuard::TakeRefusal() { return std::exchange(refusal_, std::string()); }

bool VlenGuard::Refuse(std::string why) {
  refusal_ = std::move(why);
  return false;
}

bool VlenGuard::ReadBytes(uint64_t offset, size_t size, std::string* out) {
  if (offset > file_size_ || size > file_size_ - offset) return false;
  if (!from_file_) {
    out->assign(image_.data() + offset, size);
    return true;
  }
  std::ifstream in(path_, std::ios::binary);
  if (!in) return false;
  in.seekg(static_cast<std::streamoff>(offset));
  out->resize(size);
  in.read(out->data(), static_cast<std::streamsize>(size));
  return in.gcount() == static_cast<std::streamsize>(size);
}

// The superblock libhdf5 uses: the first signature at 0, 512, 1024, 2048, ... Addresses in the
// file count from it (libhdf5 sets the base address to where it found the superblock).
bool VlenGuard::LoadSuperblock() {
  if (superblock_read_) return superblock_error_.empty();
  superblock_read_ = true;
  if (from_file_) {  // the file's size now: libhdf5 has it open (the importer checks it exists)
    std::ifstream in(path_, std::ios::binary | std::ios::ate);
    if (!in) {
      superblock_error_ = "cannot open the file";
      return false;
    }
    file_size_ = static_cast<uint64_t>(in.tellg());
  }
  static constexpr char kSignature[] = "\x89HDF\r\n\x1a\n";
  std::string sb;
  for (uint64_t at = 0; at + 8 <= file_size_; at = at == 0 ? 512 : at * 2) {
    std::string sig;
    if (!ReadBytes(at, 8, &sig) || sig != std::string_view(kSignature, 8)) continue;
    // Version 0/1: sizes at bytes 13, 14, base address at 24 (v0) or 28 (v1); 2/3: 9, 10, 12.
    if (!ReadBytes(at, std::min<uint64_t>(64, file_size_ - at), &sb) || sb.size() < 16) break;
    const auto* p = reinterpret_cast<const uint8_t*>(sb.data());
    const unsigned version = p[8];
    size_t base_at = 0;
    if (version <= 1) {
      sizeof_addr_ = p[13];
      sizeof_size_ = p[14];
      base_at = version == 0 ? 24 : 28;
    } else if (version <= 3) {
      sizeof_addr_ = p[9];
      sizeof_size_ = p[10];
      base_at = 12;
    } else {
      superblock_error_ = "superblock version " + std::to_string(version) + " is not known";
      return false;
    }
    for (unsigned s : {sizeof_addr_, sizeof_size_}) {
      if (s != 2 && s != 4 && s != 8) {
        superblock_error_ = "superblock gives " + std::to_string(s) +
                            "-byte addresses or lengths (2, 4 or 8 are read)";
        return false;
      }
    }
    if (base_at + sizeof_addr_ > sb.size()) break;
    const uint64_t base = LittleEndian(p + base_at, sizeof_addr_);
    if (base != at) {
      superblock_error_ = "superblock at byte " + std::to_string(at) + " gives base address " +
                          std::to_string(base);
      return false;
    }
    base_ = at;
    return true;
  }
  superblock_error_ = "no readable superblock";
  return false;
}

// Parses the collection as libhdf5's loader does, recording each object's size and refusing the
// layouts on which libhdf5 would read outside the collection.
const VlenGuard::Collection& VlenGuard::LoadCollection(uint64_t address) {
  auto [it, inserted] = collections_.try_emplace(address);
  Collection& c = it->second;
  if (!inserted) return c;
  const std::string at = "the global heap collection at address " + std::to_string(address);
  const uint64_t header_size = Align8(4 + 1 + 3 + sizeof_size_);    // H5HG_SIZEOF_HDR
  const uint64_t object_header = Align8(2 + 2 + 4 + sizeof_size_);  // H5HG_SIZEOF_OBJHDR
  std::string bytes;
  if (address > file_size_ - base_ || !ReadBytes(base_ + address, header_size, &bytes)) {
    c.error = at + " is outside the file (" + std::to_string(file_size_) + " bytes)";
    return c;
  }
  const auto* h = reinterpret_cast<const uint8_t*>(bytes.data());
  if (std::memcmp(h, kCollectionMagic, 4) != 0 || h[4] != 1) {
    c.error = at + " has no GCOL version 1 signature";
    return c;
  }
  const uint64_t size = LittleEndian(h + 8, sizeof_size_);
  if (size < kMinCollectionSize || size > file_size_ - base_ - address) {
    c.error = at + " declares " + std::to_string(size) + " bytes (at least " +
              std::to_string(kMinCollectionSize) + ", within the file's " +
              std::to_string(file_size_) + ")";
    return c;
  }
  if (!ReadBytes(base_ + address, static_cast<size_t>(size), &bytes)) {
    c.error = at + " cannot be read";
    return c;
  }
  const auto* chunk = reinterpret_cast<const uint8_t*>(bytes.data());
  uint64_t p = header_size;
  while (p < size) {
    if (p + object_header > size) break;  // a tail too small for an object: free space
    const unsigned index = static_cast<unsigned>(LittleEndian(chunk + p, 2));
    const uint64_t object_size = LittleEndian(chunk + p + 8, sizeof_size_);
    const std::string object =
        "object " + std::to_string(index) + " at byte " + std::to_string(p) + " of " + at;
    uint64_t need = 0;
    if (index == 0) {
      // The free space: its size includes its header and is not padded. libhdf5 steps by it
      // (a size of 0 would loop for ever; past the end, its table points outside).
      if (object_size < object_header || object_size > size - p) {
        c.error = object + " (free space) declares " + std::to_string(object_size) + " bytes";
        return c;
      }
      need = object_size;
    } else {
      if (object_size > size - p - object_header) {
        c.error = object + " declares " + std::to_string(object_size) + " bytes, past its end";
        return c;
      }
      need = object_header + Align8(object_size);
    }
    if (index >= c.objects.size()) c.objects.resize(index + 1);
    c.objects[index] = Object{object_size, true};
    p += need;
  }
  return c;
}

bool VlenGuard::CheckElements(const uint8_t* buf, size_t nelmts, size_t stride, size_t element_size,
                              size_t base_size, bool is_string) {
  if (!LoadSuperblock()) return Refuse("cannot check variable-length data: " + superblock_error_);
  const size_t disk_size = 4 + sizeof_addr_ + 4;  // length, collection address, object index
  if (element_size != disk_size) {
    return Refuse("variable-length data has " + std::to_string(element_size) +
                  "-byte elements; the file's form has " + std::to_string(disk_size));
  }
  if (stride < element_size) return Refuse("variable-length data is packed unexpectedly");
  const char* what = is_string ? "variable-length string " : "variable-length sequence ";
  for (size_t i = 0; i < nelmts; ++i) {
    const uint8_t* e = buf + i * stride;
    const uint64_t length = LittleEndian(e, 4);
    const uint64_t address = LittleEndian(e + 4, sizeof_addr_);
    const uint64_t index = LittleEndian(e + 4 + sizeof_addr_, 4);
    if (address == 0) continue;  // a null element: libhdf5 does not read the heap
    const std::string element = what + std::to_string(i);
    const Collection& c = LoadCollection(address);
    if (!c.error.empty()) return Refuse(element + " refers to " + c.error);
    const std::string object = "object " + std::to_string(index) +
                               " of the global heap collection at address " +
                               std::to_string(address);
    if (index == 0 || index >= c.objects.size() || !c.objects[index].present) {
      size_t held = 0;
      for (size_t k = 1; k < c.objects.size(); ++k) held += c.objects[k].present ? 1 : 0;
      return Refuse(element + " refers to " + object + ", which does not exist (the collection " +
                    "holds " + std::to_string(held) + " objects, numbered up to " +
                    std::to_string(c.objects.empty() ? 0 : c.objects.size() - 1) + ")");
    }
    // libhdf5 copies the whole object into a buffer sized length x element size.
    if (c.objects[index].size != length * base_size) {
      return Refuse(element + " has length " + std::to_string(length) + " but " + object +
                    " holds " + std::to_string(c.objects[index].size) + " bytes");
    }
  }
  return true;
}

}  // namespace sfrt::exporter::hdf5
