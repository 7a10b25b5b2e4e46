#include "bags/any_bag.h"

#include <filesystem>

#include "sfrt/ros2/bag_source.h"
#if SFRT_HAVE_ROS
#include "sfrt/ros/bag_source.h"
#endif

namespace sfrt::bags {

Result<BagFormat> BagFormatOf(const std::string& path) {
  const std::filesystem::path p(path);
  std::error_code ec;
  const bool rosbag2 = std::filesystem::is_directory(p, ec) || p.extension() == ".mcap" ||
                       p.extension() == ".db3" || p.extension() == ".yaml";
  if (rosbag2) {
    if (p.filename() == "metadata.yaml") return BagFormatOf(p.parent_path().string());
    return BagFormat{"rosbag2", &ros2::ProbeBag, &ros2::MakeBagSource};
  }
#if SFRT_HAVE_ROS
  return BagFormat{"ROS 1", &ros::ProbeBag, &ros::MakeBagSource};
#else
  return Status::Error("'" + path +
                       "' is a ROS 1 bag; this sfrt was built without ROS bag support (install "
                       "librosbag-dev and libsensor-msgs-dev, then configure again)");
#endif
}

}  // namespace sfrt::bags
