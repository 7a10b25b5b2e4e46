#include "ros_args.h"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cstdlib>
#include <string_view>

namespace sfrt::ros2 {
namespace {

bool IsInteger(const std::string& t) {
  size_t i = (!t.empty() && (t[0] == '-' || t[0] == '+')) ? 1 : 0;
  if (i == t.size()) return false;
  for (; i < t.size(); ++i) {
    if (!std::isdigit(static_cast<unsigned char>(t[i]))) return false;
  }
  return true;
}

bool IsDouble(const std::string& t, double* value) {
  if (t.empty() || t.find_first_of(".eE") == std::string::npos) return false;
  char* end = nullptr;
  *value = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size();
}

// A plain (unquoted) YAML scalar typed as ROS 2 types parameter values.
ParamValue TypedScalar(const std::string& text, const std::string& origin) {
  ParamValue v;
  v.text = text;
  v.origin = origin;
  if (text == "true" || text == "True" || text == "TRUE" || text == "false" || text == "False" ||
      text == "FALSE") {
    v.type = ParamValue::Type::kBool;
    v.boolean = text[0] == 't' || text[0] == 'T';
  } else if (IsInteger(text)) {
    v.type = ParamValue::Type::kInteger;
    v.integer = std::strtoll(text.c_str(), nullptr, 10);
  } else if (IsDouble(text, &v.real)) {
    v.type = ParamValue::Type::kDouble;
  }
  return v;
}

// "NAME:=VALUE" split; false when there is no ":=".
bool SplitAssignment(std::string_view arg, std::string* name, std::string* value) {
  const size_t at = arg.find(":=");
  if (at == std::string_view::npos || at == 0) return false;
  *name = std::string(arg.substr(0, at));
  *value = std::string(arg.substr(at + 2));
  return true;
}

ParamValue ParamFromCommandLine(const std::string& name, const std::string& value) {
  const std::string origin = "-p " + name + ":=" + value;
  const bool quoted = value.size() >= 2 && (value.front() == '"' || value.front() == '\'') &&
                      value.back() == value.front();
  if (!quoted) return TypedScalar(value, origin);
  ParamValue v;
  v.text = value.substr(1, value.size() - 2);
  v.origin = origin;
  return v;
}

// Whether a params file's top-level key names this node.
bool KeyNamesNode(const std::string& key, const RosArgs& args) {
  if (key == "/**" || key == args.node_name) return true;
  const std::string ns = args.node_namespace == "/" ? "" : args.node_namespace;
  return key == ns + "/" + args.node_name || key == "/**/" + args.node_name;
}

Status AddParams(const YAML::Node& map, const std::string& prefix, const std::string& file,
                 RosArgs* args) {
  for (const auto& entry : map) {
    const std::string name = prefix + entry.first.as<std::string>();
    const YAML::Node& value = entry.second;
    if (value.IsMap()) {
      if (Status s = AddParams(value, name + ".", file, args); !s.ok()) return s;
    } else if (value.IsScalar()) {
      ParamValue v = value.Tag() == "!" ? ParamValue{} : TypedScalar(value.Scalar(), file);
      if (value.Tag() == "!") {
        v.text = value.Scalar();
        v.origin = file;
      }
      args->params[name] = v;
    } else {
      return Status::Error("'" + file + "': parameter '" + name +
                           "' is a list or empty; sfrt_ros2's parameters are single values");
    }
  }
  return Status::Ok();
}

Status LoadParamsFile(const std::string& file, RosArgs* args) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    return Status::Error("--params-file '" + file + "': " + e.what());
  }
  if (!root.IsMap()) {
    return Status::Error("--params-file '" + file +
                         "' is not ROS 2 parameters (<node>: ros__parameters: ...)");
  }
  try {
    for (const auto& node : root) {
      if (!KeyNamesNode(node.first.as<std::string>(), *args)) continue;
      const YAML::Node params = node.second["ros__parameters"];
      if (!params || !params.IsMap()) {
        return Status::Error("--params-file '" + file + "': '" + node.first.as<std::string>() +
                             "' has no ros__parameters map");
      }
      if (Status s = AddParams(params, "", file, args); !s.ok()) return s;
    }
  } catch (const YAML::Exception& e) {
    return Status::Error("--params-file '" + file + "': " + e.what());
  }
  return Status::Ok();
}

// The part of a ROS 2 name check sfrt needs: letters, digits, '_' and '/', no "//", not empty.
Status CheckName(const std::string& name, const std::string& what) {
  if (name.empty()) return Status::Error(what + " is empty");
  if (name.find("//") != std::string::npos || name.find('~') != std::string::npos) {
    return Status::Error(what + " '" + name + "' is not a valid ROS 2 name");
  }
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '/') {
      return Status::Error(what + " '" + name + "' has a '" + std::string(1, c) +
                           "', which ROS 2 names do not allow");
    }
  }
  return Status::Ok();
}

std::string Qualify(const std::string& ns, const std::string& name) {
  if (!name.empty() && name.front() == '/') return name;
  return (ns == "/" ? "" : ns) + "/" + name;
}

// One argument inside --ros-args; *i moves past what it used.
Status RosArgument(int argc, const char* const* argv, int* i, RosArgs* args,
                   std::vector<std::pair<std::string, std::string>>* remaps,
                   std::vector<std::pair<std::string, ParamValue>>* params,
                   std::vector<std::string>* files) {
  const std::string flag = argv[*i];
  const bool param = flag == "-p" || flag == "--param";
  const bool remap = flag == "-r" || flag == "--remap";
  const bool file = flag == "--params-file";
  if (!param && !remap && !file) {
    return Status::Error("--ros-args: '" + flag +
                         "' is not one sfrt_ros2 takes (-p, -r, --params-file)");
  }
  if (*i + 1 >= argc) return Status::Error("--ros-args: " + flag + " needs a value");
  const std::string value = argv[++*i];
  if (file) {
    files->push_back(value);
    return Status::Ok();
  }
  std::string name, assigned;
  if (!SplitAssignment(value, &name, &assigned)) {
    return Status::Error("--ros-args: " + flag + " '" + value + "' is not NAME:=VALUE");
  }
  if (param) {
    params->push_back({name, ParamFromCommandLine(name, assigned)});
  } else if (name == "__node" || name == "__name") {
    args->node_name = assigned;
  } else if (name == "__ns") {
    args->node_namespace = assigned.empty() || assigned.front() != '/' ? "/" + assigned : assigned;
  } else {
    remaps->push_back({name, assigned});
  }
  return Status::Ok();
}

}  // namespace

Result<RosArgs> ParseRosArgs(int argc, const char* const* argv, const std::string& default_name) {
  RosArgs args;
  args.node_name = default_name;
  std::vector<std::pair<std::string, std::string>> remaps;
  std::vector<std::pair<std::string, ParamValue>> params;
  std::vector<std::string> files;
  bool in_ros_args = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--ros-args") {
      in_ros_args = true;
    } else if (a == "--" && in_ros_args) {
      in_ros_args = false;
    } else if (in_ros_args) {
      if (Status s = RosArgument(argc, argv, &i, &args, &remaps, &params, &files); !s.ok()) {
        return s;
      }
    } else {
      if (a == "-h" || a == "--help") args.help = true;
      args.program_args.push_back(a);
    }
  }
  if (Status s = CheckName(args.node_name, "the node's name (__node)"); !s.ok()) return s;
  if (Status s = CheckName(args.node_namespace, "the namespace (__ns)"); !s.ok()) return s;
  for (const std::string& f : files) {
    if (Status s = LoadParamsFile(f, &args); !s.ok()) return s;
  }
  for (auto& [name, value] : params) args.params[name] = value;  // -p after the files
  for (const auto& [from, to] : remaps) {
    if (Status s = CheckName(from, "remapping '" + from + ":=" + to + "'"); !s.ok()) return s;
    if (Status s = CheckName(to, "remapping '" + from + ":=" + to + "'"); !s.ok()) return s;
    args.remaps.push_back({Qualify(args.node_namespace, from), Qualify(args.node_namespace, to)});
  }
  return args;
}

Result<std::string> ResolveTopic(const RosArgs& args, const std::string& topic) {
  if (Status s = CheckName(topic, "topic"); !s.ok()) return s;
  const std::string name = Qualify(args.node_namespace, topic);
  for (const auto& [from, to] : args.remaps) {
    if (from == name) return to;
  }
  return name;
}

}  // namespace sfrt::ros2
