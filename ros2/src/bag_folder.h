// Where a rosbag2 bag's messages are: `ros2 bag record` writes a folder holding metadata.yaml and
// the storage files it lists (one, or several when the bag was split by size or duration), each
// .mcap or .db3. sfrt also takes one storage file on its own (a single .mcap, as Foxglove and the
// mcap CLI write, or a .db3) and a folder whose metadata.yaml is missing (a recording cut short:
// its .mcap or .db3 files are taken in name order). Not installed.
#pragma once

#include <string>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2 {

enum class Storage { kMcap, kSqlite3 };

struct BagFile {
  std::string path;
  Storage storage = Storage::kMcap;
};

struct BagLayout {
  std::vector<BagFile> files;  // in the order to read them
  bool has_metadata = false;   // read from metadata.yaml (else found by name)
  std::string ros_distro;      // metadata.yaml's, when it says
};

// Resolves `path` (a bag folder, a .mcap or a .db3 file). Refused, naming the path and why: a
// path that does not exist, a folder with no storage file, a metadata.yaml that is not rosbag2's
// (naming the field), a storage other than mcap and sqlite3, files compressed whole by rosbag2
// (compression_mode FILE: `ros2 bag convert` writes them uncompressed; compressed MCAP chunks are
// read), a listed file that is missing.
Result<BagLayout> ResolveBagLayout(const std::string& path);

}  // namespace sfrt::ros2
