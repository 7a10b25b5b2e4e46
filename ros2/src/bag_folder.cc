#include "bag_folder.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <system_error>

namespace sfrt::ros2 {
namespace {

namespace fs = std::filesystem;

bool EndsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// The storage a file's name says, or an error naming it.
Result<Storage> StorageOfName(const std::string& path) {
  if (EndsWith(path, ".mcap")) return Storage::kMcap;
  if (EndsWith(path, ".db3")) return Storage::kSqlite3;
  if (EndsWith(path, ".zstd") || EndsWith(path, ".lz4")) {
    return Status::Error("'" + path +
                         "' is compressed whole (rosbag2 compression_mode FILE); sfrt reads "
                         "uncompressed files (`ros2 bag convert` writes them)");
  }
  return Status::Error("'" + path + "' is neither a .mcap nor a .db3 file");
}

// A folder without metadata.yaml: its storage files in name order.
Result<BagLayout> FilesByName(const fs::path& folder) {
  BagLayout layout;
  std::error_code ec;
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && (EndsWith(name, ".mcap") || EndsWith(name, ".db3"))) {
      names.push_back(name);
    }
  }
  if (ec) return Status::Error("cannot list '" + folder.string() + "': " + ec.message());
  if (names.empty()) {
    return Status::Error("'" + folder.string() +
                         "' holds no metadata.yaml and no .mcap or .db3 file: not a rosbag2 bag");
  }
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) {
    layout.files.push_back({(folder / name).string(), *StorageOfName(name)});
  }
  return layout;
}

// A listed file: relative to the bag folder. Bags of metadata version < 4 list it with the
// folder's own name in front ("bag/bag_0.db3"), so its last component is tried too.
Result<std::string> ListedFile(const fs::path& folder, const std::string& listed) {
  const fs::path direct = folder / listed;
  if (fs::exists(direct)) return direct.string();
  const fs::path by_name = folder / fs::path(listed).filename();
  if (fs::exists(by_name)) return by_name.string();
  return Status::Error("'" + (folder / "metadata.yaml").string() + "' lists '" + listed +
                       "', which is not in the folder (a bag copied in part?)");
}

Result<BagLayout> FromMetadata(const fs::path& folder) {
  const std::string file = (folder / "metadata.yaml").string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    return Status::Error("cannot read '" + file + "': " + e.what());
  }
  const YAML::Node info = root["rosbag2_bagfile_information"];
  if (!info || !info.IsMap()) {
    return Status::Error("'" + file + "' has no rosbag2_bagfile_information: not a rosbag2 bag");
  }
  try {
    const std::string storage = info["storage_identifier"].as<std::string>("");
    if (storage != "mcap" && storage != "sqlite3") {
      return Status::Error("'" + file + "': storage_identifier '" + storage +
                           "' is not one sfrt reads (mcap, sqlite3)");
    }
    if (info["compression_mode"].as<std::string>("") == "FILE") {
      return Status::Error("'" + file + "': compression_mode FILE (" +
                           info["compression_format"].as<std::string>("") +
                           "): sfrt reads uncompressed files (`ros2 bag convert` writes them)");
    }
    BagLayout layout;
    layout.has_metadata = true;
    layout.ros_distro = info["ros_distro"].as<std::string>("");
    const YAML::Node paths = info["relative_file_paths"];
    if (!paths || !paths.IsSequence() || paths.size() == 0) {
      return Status::Error("'" + file + "': relative_file_paths lists no file");
    }
    for (const YAML::Node& p : paths) {
      Result<std::string> path = ListedFile(folder, p.as<std::string>());
      if (!path.ok()) return path.status();
      layout.files.push_back({*path, storage == "mcap" ? Storage::kMcap : Storage::kSqlite3});
    }
    return layout;
  } catch (const YAML::Exception& e) {
    return Status::Error("'" + file + "': " + e.what());
  }
}

}  // namespace

Result<BagLayout> ResolveBagLayout(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) return Status::Error("'" + path + "' does not exist");
  if (fs::is_directory(st)) {
    if (fs::exists(fs::path(path) / "metadata.yaml")) return FromMetadata(path);
    return FilesByName(path);
  }
  Result<Storage> storage = StorageOfName(path);
  if (!storage.ok()) return storage.status();
  BagLayout layout;
  layout.files.push_back({path, *storage});
  return layout;
}

}  // namespace sfrt::ros2
