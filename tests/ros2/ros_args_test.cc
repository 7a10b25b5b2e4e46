// The ROS 2 command line as sfrt_ros2 reads it (ros2/src/ros_args.h): parameters typed as ROS 2
// types them, params files, remappings, namespace and node name, and the errors.
#include "ros_args.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace sfrt::ros2 {
namespace {

Result<RosArgs> Parse(std::vector<const char*> argv) {
  argv.insert(argv.begin(), "sfrt_ros2");
  return ParseRosArgs(static_cast<int>(argv.size()), argv.data(), "sfrt_ros2");
}

TEST(RosArgs, ParametersAreTypedAsRos2TypesThem) {
  Result<RosArgs> a = Parse({"--ros-args", "-p", "threads:=2", "-p", "budget_ms:=20.5", "-p",
                             "publish_vis:=true", "-p", "size:=96x128", "-p", "frame_id:='7'"});
  ASSERT_TRUE(a.ok()) << a.message();
  EXPECT_EQ(a->params["threads"].type, ParamValue::Type::kInteger);
  EXPECT_EQ(a->params["threads"].integer, 2);
  EXPECT_EQ(a->params["budget_ms"].type, ParamValue::Type::kDouble);
  EXPECT_DOUBLE_EQ(a->params["budget_ms"].real, 20.5);
  EXPECT_EQ(a->params["publish_vis"].type, ParamValue::Type::kBool);
  EXPECT_TRUE(a->params["publish_vis"].boolean);
  EXPECT_EQ(a->params["size"].type, ParamValue::Type::kString);
  EXPECT_EQ(a->params["size"].text, "96x128");
  EXPECT_EQ(a->params["frame_id"].type, ParamValue::Type::kString);  // quoted: a string
  EXPECT_EQ(a->params["frame_id"].text, "7");
}

TEST(RosArgs, NamespaceNodeNameAndRemappingsResolveTopics) {
  Result<RosArgs> a = Parse({"--ros-args", "-r", "__ns:=/robot1", "-r", "__node:=flow", "-r",
                             "left/image_rect:=/cam/left/image_rect"});
  ASSERT_TRUE(a.ok()) << a.message();
  EXPECT_EQ(a->node_name, "flow");
  EXPECT_EQ(a->node_namespace, "/robot1");
  EXPECT_EQ(*ResolveTopic(*a, "left/image_rect"), "/cam/left/image_rect");
  EXPECT_EQ(*ResolveTopic(*a, "right/image_rect"), "/robot1/right/image_rect");
  EXPECT_EQ(*ResolveTopic(*a, "/diagnostics"), "/diagnostics");
  EXPECT_FALSE(ResolveTopic(*a, "bad name").ok());
}

TEST(RosArgs, AParamsFileAppliesToThisNodeAndCommandLineParametersWin) {
  const std::string file = testing::TempDir() + "sfrt_ros_args_params.yaml";
  std::ofstream(file) << "other_node:\n  ros__parameters:\n    model: other.sfrt\n"
                         "/robot1/flow:\n  ros__parameters:\n    model: m.sfrt\n    threads: 4\n"
                         "    size: \"96x128\"\n    nested:\n      depth: 3\n"
                         "/**:\n  ros__parameters:\n    qos: sensor_data\n";
  Result<RosArgs> a = Parse({"--ros-args", "-r", "__ns:=/robot1", "-r", "__node:=flow",
                             "--params-file", file.c_str(), "-p", "threads:=2"});
  ASSERT_TRUE(a.ok()) << a.message();
  EXPECT_EQ(a->params["model"].text, "m.sfrt");
  EXPECT_EQ(a->params["threads"].integer, 2);  // -p after the file
  EXPECT_EQ(a->params["size"].type, ParamValue::Type::kString);
  EXPECT_EQ(a->params["nested.depth"].integer, 3);
  EXPECT_EQ(a->params["qos"].text, "sensor_data");
  std::filesystem::remove(file);
}

TEST(RosArgs, ProgramArgumentsStayOutsideRosArgs) {
  Result<RosArgs> a = Parse({"--help", "--ros-args", "-p", "model:=m.sfrt", "--", "extra"});
  ASSERT_TRUE(a.ok()) << a.message();
  EXPECT_TRUE(a->help);
  EXPECT_EQ(a->program_args, (std::vector<std::string>{"--help", "extra"}));
}

TEST(RosArgs, ErrorsNameTheArgument) {
  Result<RosArgs> a = Parse({"--ros-args", "--log-level", "debug"});
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.message().find("'--log-level'"), std::string::npos) << a.message();
  a = Parse({"--ros-args", "-p", "model"});
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.message().find("-p 'model' is not NAME:=VALUE"), std::string::npos) << a.message();
  a = Parse({"--ros-args", "-p"});
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.message().find("-p needs a value"), std::string::npos) << a.message();
  a = Parse({"--ros-args", "--params-file", "/nonexistent/params.yaml"});
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.message().find("/nonexistent/params.yaml"), std::string::npos) << a.message();
  a = Parse({"--ros-args", "-r", "__node:=bad-name"});
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.message().find("bad-name"), std::string::npos) << a.message();
}

}  // namespace
}  // namespace sfrt::ros2
