// A ROS 2 program's command line, as rcl reads it, for a node without rclcpp (sfrt_ros2):
//
//   sfrt_ros2 [--ros-args [-p NAME:=VALUE]... [-r FROM:=TO]... [--params-file FILE]...
//             [--remap FROM:=TO] [--param NAME:=VALUE] [--]]
//
//   -p/--param NAME:=VALUE   a parameter; VALUE is read as a YAML scalar, as ROS 2 does ("2" an
//                            integer, "2.5" a double, "true" a bool, anything else a string)
//   -r/--remap FROM:=TO      a topic remapping; FROM and TO are resolved against the node's
//                            namespace first. The special names `__ns` (the namespace) and
//                            `__node` (the node's name) set those.
//   --params-file FILE       parameters in ROS 2's YAML form:
//                              <node name or /namespace/name or /**>:
//                                ros__parameters:
//                                  model: m.sfrt
//                            applied in the order given; -p overrides a file's value.
//   -e/--enclave, --log-level and the rest of rcl's options are refused by name (not supported).
// Arguments outside --ros-args ... -- are the program's own and are returned as they came.
// Errors name the argument and why. Not installed.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2 {

// A parameter's value, typed as ROS 2 types it.
struct ParamValue {
  enum class Type { kString, kInteger, kDouble, kBool };
  Type type = Type::kString;
  std::string text;  // the string, or the number or bool as written
  int64_t integer = 0;
  double real = 0;
  bool boolean = false;
  std::string origin;  // "-p model:=x" or "params.yaml": where it was set, for messages
};

struct RosArgs {
  std::string node_name;
  std::string node_namespace = "/";
  std::vector<std::pair<std::string, std::string>> remaps;  // resolved names, in order
  std::map<std::string, ParamValue> params;
  std::vector<std::string> program_args;  // outside --ros-args
  bool help = false;                      // -h or --help among the program's arguments
};

// Parses argv. `default_name` is the node's name unless __node renames it.
Result<RosArgs> ParseRosArgs(int argc, const char* const* argv, const std::string& default_name);

// A topic's fully qualified name: "flow" in namespace "/robot1" is "/robot1/flow"; "/flow" stays;
// then the first remapping whose FROM equals it gives TO. Errors name a name ROS 2 refuses (empty,
// with "//", a character other than letters, digits, '_' and '/', or "~" which only private
// names use).
Result<std::string> ResolveTopic(const RosArgs& args, const std::string& topic);

}  // namespace sfrt::ros2
