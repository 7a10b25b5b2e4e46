// Object-header layout (HDF5 File Format Specification 3.0, "Data Object Headers"):
//  version 1: version (1), reserved (1), message count (2), reference count (4), chunk-0 size
//    (4), 4 bytes of padding; chunk 0's messages follow (16 bytes from the header's address).
//    Message header: type (2), data size (2), flags (1), reserved (3); data 8-byte aligned.
//    A continuation chunk holds messages only.
//  version 2: "OHDR", version 2, flags; access/modification/change/birth times (4 x 4 bytes,
//    flags bit 5); maximum compact / minimum dense attribute counts (2 x 2 bytes, flags bit 4);
//    chunk-0 size in 1, 2, 4 or 8 bytes (flags bits 0-1); messages; a gap; a 4-byte checksum.
//    Message header: type (1), data size (2), flags (1), creation order (2, flags bit 2 of the
//    header). A continuation chunk is "OCHK", messages, a gap, a checksum; its length in the
//    continuation message counts all of them.
//  Continuation message (type 0x0010): chunk address (sizeof offsets), chunk length (sizeof
//    lengths).
// Checksums are not verified (libhdf5 does; the guard only keeps it from over-allocating).
#include "hdf5_header_guard.h"

#include <cstring>
#include <filesystem>
#include <utility>

namespace sfrt::exporter::hdf5 {
namespace {

constexpr char kSignature[] = "\x89HDF\r\n\x1a\n";
constexpr unsigned kContinuation = 0x0010;
constexpr unsigned kAttribute = 0x000C;
constexpr unsigned kSharedFlag = 0x02;  // message flags bit 1: the data is a shared reference

uint64_t LittleEndian(const uint8_t* p, unsigned bytes) {
  uint64_t v = 0;
  for (unsigned i = bytes; i > 0; --i) v = (v << 8) | p[i - 1];
  return v;
}

uint64_t Align8(uint64_t n) { return n + ((8 - n % 8) % 8); }

const uint8_t* Bytes(const std::string& s) { return reinterpret_cast<const uint8_t*>(s.data()); }

// An attribute message (not shared): version 1 to 3, then flags/reserved, name size, datatype
// size, dataspace size (2 bytes each), the encoding (version 3), then the name (with its NUL),
// datatype and dataspace, each padded to 8 bytes in version 1. libhdf5 1.10.8 decodes them
// without comparing these sizes with the message's (H5O_attr_decode). "" when sound.
std::string AttributeProblem(const uint8_t* p, uint64_t size, unsigned sizeof_addr,
                             unsigned sizeof_size) {
  if (size < 8) return "is " + std::to_string(size) + " bytes (under 8)";
  const unsigned version = p[0];
  if (version < 1 || version > 3) return "has version " + std::to_string(version) + " (1 to 3)";
  const uint64_t name = LittleEndian(p + 2, 2);
  uint64_t type = LittleEndian(p + 4, 2);
  uint64_t space = LittleEndian(p + 6, 2);
  const uint64_t at = version == 3 ? 9 : 8;
  const uint64_t padded_name = version == 1 ? Align8(name) : name;
  if (version == 1) {
    type = Align8(type);
    space = Align8(space);
  }
  if (name == 0) return "has name size 0";
  if (at + padded_name + type + space > size) {
    return "has name size " + std::to_string(name) + ", datatype size " +
           std::to_string(LittleEndian(p + 4, 2)) + " and dataspace size " +
           std::to_string(LittleEndian(p + 6, 2)) + ", more than its " + std::to_string(size) +
           " bytes";
  }
  if (p[at + name - 1] != 0) return "has a name of " + std::to_string(name) + " bytes without NUL";
  // The data: as many elements as the dataspace has points, each of the datatype's size (the
  // datatype message's bytes 4-7; the dataspace message: version, rank, flags, then in version 1
  // five reserved bytes, in version 2 the type: 0 scalar, 1 simple, 2 null; then the sizes).
  const uint8_t* dt = p + at + padded_name;
  const uint8_t* ds = dt + type;
  const uint64_t data_at = at + padded_name + type + space;
  if (LittleEndian(p + 4, 2) < 8 || LittleEndian(p + 6, 2) < 4) return "has no room for its types";
  const uint64_t element = LittleEndian(dt + 4, 4);
  // A variable-length datatype (class 9) stores a global-heap ID per element: a 4-byte length,
  // the collection's address and a 4-byte index. libhdf5 replaces the size the message gives with
  // that when it opens the attribute (H5T_set_loc) and then copies that many bytes per element
  // from data it allocated at the message's size, so the two must agree.
  // Its base type (the 8 bytes after the variable-length type's own) sizes each item of a
  // sequence; libhdf5 allocates length x that size per element when it converts. The importer
  // reads variable-length strings only, whose items are 1-byte characters.
  if ((dt[0] & 0x0F) == 9) {
    if (element != 8 + uint64_t{sizeof_addr}) {
      return "has a variable-length datatype of " + std::to_string(element) +
             " bytes per element; a heap ID takes " + std::to_string(8 + sizeof_addr);
    }
    if (LittleEndian(p + 4, 2) < 16) return "has a variable-length datatype without its base type";
    const uint64_t item = LittleEndian(dt + 8 + 4, 4);
    if (item != 1) {
      return "has a variable-length datatype of " + std::to_string(item) +
             "-byte items; strings have 1-byte characters";
    }
  }
  const unsigned rank = ds[1];
  const uint64_t dims_at = ds[0] == 1 ? 8 : 4;
  uint64_t points = ds[0] == 2 && ds[3] == 2 ? 0 : 1;
  if (dims_at + uint64_t{rank} * sizeof_size > LittleEndian(p + 6, 2)) {
    return "has a dataspace of rank " + std::to_string(rank) + " in " +
           std::to_string(LittleEndian(p + 6, 2)) + " bytes";
  }
  for (unsigned d = 0; d < rank && points > 0; ++d) {
    const uint64_t n = LittleEndian(ds + dims_at + d * uint64_t{sizeof_size}, sizeof_size);
    points = n != 0 && points > size / n ? size + 1 : points * n;
  }
  if (points > 0 && (element == 0 || points > (size - data_at) / element)) {
    return "holds " + std::to_string(points) + " elements of " + std::to_string(element) +
           " bytes in " + std::to_string(size - data_at) + " bytes";
  }
  return "";
}

}  // namespace

HeaderGuard::HeaderGuard(std::string_view image) : image_(image), file_size_(image.size()) {}

HeaderGuard::HeaderGuard(std::string path) : path_(std::move(path)), from_file_(true) {}

bool HeaderGuard::ReadBytes(uint64_t offset, uint64_t size, std::string* out) {
  if (offset > file_size_ || size > file_size_ - offset) return false;
  if (!from_file_) {
    out->assign(image_.data() + offset, static_cast<size_t>(size));
    return true;
  }
  in_.clear();
  in_.seekg(static_cast<std::streamoff>(offset));
  out->resize(static_cast<size_t>(size));
  in_.read(out->data(), static_cast<std::streamsize>(size));
  return in_.gcount() == static_cast<std::streamsize>(size);
}

// The superblock libhdf5 uses: the first signature at 0, 512, 1024, 2048, ...; file addresses
// count from it.
Status HeaderGuard::LoadSuperblock() {
  if (superblock_read_) return superblock_;
  superblock_read_ = true;
  if (from_file_) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path_, ec);
    in_.open(path_, std::ios::binary);
    if (ec || !in_) return superblock_ = Status::Error("cannot read the file");
    file_size_ = size;
  }
  for (uint64_t at = 0; at + 8 <= file_size_; at = at == 0 ? 512 : at * 2) {
    std::string sb;
    if (!ReadBytes(at, 8, &sb) || sb != std::string_view(kSignature, 8)) continue;
    if (!ReadBytes(at, std::min<uint64_t>(128, file_size_ - at), &sb) || sb.size() < 16) break;
    const uint8_t* p = Bytes(sb);
    const unsigned version = p[8];
    size_t root_at = 0;
    size_t extension_at = 0;  // 0: none (superblock versions 0 and 1)
    if (version <= 1) {
      sizeof_addr_ = p[13];
      sizeof_size_ = p[14];
      // Base, free-space, end-of-file and driver addresses, then the root symbol table entry:
      // link name offset, object header address.
      root_at = (version == 0 ? 24 : 28) + 5 * size_t{sizeof_addr_};
    } else if (version <= 3) {
      sizeof_addr_ = p[9];
      sizeof_size_ = p[10];
      // Base, superblock extension and end-of-file addresses, then the root header address.
      root_at = 12 + 3 * size_t{sizeof_addr_};
      extension_at = 12 + size_t{sizeof_addr_};
    } else {
      return superblock_ = Status::Error("superblock version " + std::to_string(version) +
                                         " is not known (0 to 3 are)");
    }
    for (unsigned s : {sizeof_addr_, sizeof_size_}) {
      if (s != 2 && s != 4 && s != 8) {
        return superblock_ = Status::Error("superblock gives " + std::to_string(s) +
                                           "-byte addresses or lengths (2, 4 or 8 are read)");
      }
    }
    if (root_at + sizeof_addr_ > sb.size()) break;
    base_ = at;
    root_ = LittleEndian(p + root_at, sizeof_addr_);
    if (extension_at != 0) {
      extension_ = LittleEndian(p + extension_at, sizeof_addr_);
      // The undefined address is all bits set.
      if (sizeof_addr_ < 8 && extension_ == (uint64_t{1} << (8 * sizeof_addr_)) - 1) {
        extension_ = kUndefined;
      }
    }
    return superblock_ = Status::Ok();
  }
  return superblock_ = Status::Error("no complete superblock in its " + std::to_string(file_size_) +
                                     " bytes");
}

Status HeaderGuard::CheckRoot() {
  if (Status sb = LoadSuperblock(); !sb.ok()) return sb;
  // H5Fopen reads the superblock extension (an object header) before the root group's.
  if (extension_ != kUndefined) {
    if (Status s = CheckObject(extension_, "the superblock extension"); !s.ok()) return s;
  }
  return CheckObject(root_, "the root group");
}

Status HeaderGuard::WalkMessages(const std::string& where, int index, const uint8_t* p,
                                 uint64_t size, int version, bool creation_order,
                                 std::vector<Chunk>* queue) const {
  const uint64_t header = version == 1 ? 8 : (creation_order ? 6 : 4);
  const uint64_t space = file_size_ - base_;  // addresses 0 .. space-1 lie in the file
  const std::string file = " (" + std::to_string(space) + " bytes from the superblock)";
  uint64_t pos = 0;
  for (int m = 0; size - pos >= header; ++m) {
    const unsigned type = version == 1 ? static_cast<unsigned>(LittleEndian(p + pos, 2)) : p[pos];
    uint64_t data = LittleEndian(p + pos + (version == 1 ? 2 : 1), 2);
    const unsigned flags = p[pos + (version == 1 ? 4 : 3)];
    if (version == 1) data = Align8(data);
    pos += header;
    const std::string what = where + ": message " + std::to_string(m) + " (type " +
                             std::to_string(type) + ") of chunk " + std::to_string(index);
    if (data > size - pos) {
      return Status::Error(what + " has size " + std::to_string(data) + ", past its chunk's end (" +
                           std::to_string(size - pos) + " bytes left)");
    }
    if (type == kAttribute && (flags & kSharedFlag) == 0) {
      if (std::string problem = AttributeProblem(p + pos, data, sizeof_addr_, sizeof_size_);
          !problem.empty()) {
        return Status::Error(what + ", an attribute message, " + problem);
      }
    }
    if (type == kContinuation) {
      if (data < sizeof_addr_ + sizeof_size_) {
        return Status::Error(what + ", a continuation message, has size " + std::to_string(data) +
                             " (under " + std::to_string(sizeof_addr_ + sizeof_size_) + ")");
      }
      const uint64_t address = LittleEndian(p + pos, sizeof_addr_);
      const uint64_t length = LittleEndian(p + pos + sizeof_addr_, sizeof_size_);
      const std::string cont = what + ", a continuation message, gives chunk ";
      if (address >= space) {
        return Status::Error(cont + "address " + std::to_string(address) +
                             ", past the end of the file" + file);
      }
      if (length > space - address) {
        return Status::Error(cont + "length " + std::to_string(length) + " at address " +
                             std::to_string(address) + ", past the end of the file" + file);
      }
      const uint64_t least = version == 1 ? 8 : 8 + header;  // OCHK + checksum (+ a message)
      if (length < least) {
        return Status::Error(cont + "length " + std::to_string(length) + " at address " +
                             std::to_string(address) + " (under " + std::to_string(least) +
                             " bytes)");
      }
      queue->push_back({address, length});
    }
    pos += data;
  }
  return Status::Ok();
}

Status HeaderGuard::CheckObject(uint64_t address, const std::string& name) {
  if (Status sb = LoadSuperblock(); !sb.ok()) {
    return Status::Error("cannot check the object header of " + name + ": " + sb.message());
  }
  if (checked_.count(address) > 0) return Status::Ok();
  const std::string where = "object header of " + name + " at address " + std::to_string(address);
  const uint64_t space = file_size_ - base_;
  const std::string file = " (" + std::to_string(space) + " bytes from the superblock)";
  if (address >= space) {
    return Status::Error(where + ": the address is past the end of the file" + file);
  }
  std::string prefix;
  if (!ReadBytes(base_ + address, std::min<uint64_t>(64, space - address), &prefix)) {
    return Status::Error(where + ": cannot read the file");
  }
  const uint8_t* p = Bytes(prefix);
  int version = 0;
  bool creation_order = false;
  uint64_t messages_at = 0;  // chunk 0's messages: offset from the header's address
  uint64_t chunk0 = 0;       // and their size
  uint64_t trailer = 0;      // bytes after them (the checksum)
  if (prefix.size() >= 4 && std::memcmp(p, "OHDR", 4) == 0) {
    version = 2;
    if (prefix.size() < 6 || p[4] != 2) {
      return Status::Error(where + ": OHDR version " +
                           (prefix.size() < 6 ? std::string("missing") : std::to_string(p[4])) +
                           " (2 is read)");
    }
    const unsigned flags = p[5];
    creation_order = (flags & 0x04) != 0;
    uint64_t pos = 6 + ((flags & 0x20) != 0 ? 16 : 0) + ((flags & 0x10) != 0 ? 4 : 0);
    const unsigned width = 1u << (flags & 0x03);
    if (pos + width > prefix.size()) {
      return Status::Error(where + ": the header prefix runs past the end of the file" + file);
    }
    chunk0 = LittleEndian(p + pos, width);
    messages_at = pos + width;
    trailer = 4;
  } else if (!prefix.empty() && p[0] == 1) {
    version = 1;
    if (prefix.size() < 16) {
      return Status::Error(where + ": the header prefix runs past the end of the file" + file);
    }
    chunk0 = LittleEndian(p + 8, 4);
    messages_at = 16;
  } else {
    return Status::Error(where + ": no OHDR signature and version " +
                         (prefix.empty() ? std::string("missing") : std::to_string(p[0])) +
                         " (1 or 2 are read)");
  }
  if (chunk0 > space - address - messages_at || trailer > space - address - messages_at - chunk0) {
    return Status::Error(where + ": chunk 0 size " + std::to_string(chunk0) +
                         " runs past the end of the file" + file);
  }
  std::set<uint64_t> seen = {address};
  std::vector<Chunk> queue;
  std::string bytes;
  if (!ReadBytes(base_ + address + messages_at, chunk0, &bytes)) {
    return Status::Error(where + ": cannot read the file");
  }
  if (Status s = WalkMessages(where, 0, Bytes(bytes), chunk0, version, creation_order, &queue);
      !s.ok()) {
    return s;
  }
  for (size_t i = 0; i < queue.size(); ++i) {
    const Chunk c = queue[i];
    const int index = static_cast<int>(i) + 1;
    if (index >= kMaxChunks) {
      return Status::Error(where + ": more than " + std::to_string(kMaxChunks) + " chunks");
    }
    if (!seen.insert(c.address).second) {
      return Status::Error(where + ": continuation chunk " + std::to_string(index) +
                           " is at address " + std::to_string(c.address) +
                           ", a chunk already read (a loop)");
    }
    if (!ReadBytes(base_ + c.address, c.length, &bytes)) {
      return Status::Error(where + ": cannot read the file");
    }
    const uint8_t* data = Bytes(bytes);
    uint64_t size = c.length;
    if (version == 2) {
      if (std::memcmp(data, "OCHK", 4) != 0) {
        return Status::Error(where + ": continuation chunk " + std::to_string(index) +
                             " at address " + std::to_string(c.address) + " has no OCHK signature");
      }
      data += 4;
      size -= 8;
    }
    if (Status s = WalkMessages(where, index, data, size, version, creation_order, &queue);
        !s.ok()) {
      return s;
    }
  }
  checked_.insert(address);
  return Status::Ok();
}

}  // namespace sfrt::exporter::hdf5
