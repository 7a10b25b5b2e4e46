// sfrt report compare A.json B.json: the change per stage and per layer between two
// `sfrt run --profile` reports (sfrt/pipeline/profile_report.h).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "sfrt/commands.h"
#include "sfrt/pipeline/profile_report.h"

namespace sfrt::tools {
namespace {

struct ReportArgs {
  std::string a;
  std::string b;
};

int RunCompare(const ReportArgs& args) {
  std::string paths[2] = {args.a, args.b};
  for (std::string& path : paths) {
    // A --profile directory stands for the profile.json sfrt run wrote into it.
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
      path = (std::filesystem::path(path) / "profile.json").string();
    if (std::string problem = CheckInputFile(path, "profile report"); !problem.empty()) {
      return ReportError("report compare", problem, kExitFailure);
    }
  }
  Result<std::string> table = pipeline::CompareProfileFiles(paths[0], paths[1]);
  if (!table.ok()) return ReportError("report compare", table.message(), kExitFailure);
  std::cout << *table;
  return kExitOk;
}

}  // namespace

Command AddReportCommand(CLI::App& parent) {
  CLI::App* cmd = parent.add_subcommand("report", "Compare profiles written by sfrt run --profile");
  cmd->require_subcommand(1);
  auto args = std::make_shared<ReportArgs>();
  CLI::App* compare = cmd->add_subcommand(
      "compare", "Change per stage and per layer between two profile.json files");
  compare->add_option("a", args->a, "Profile A (the reference): DIR/profile.json, or DIR")
      ->required();
  compare->add_option("b", args->b, "Profile B (the candidate)")->required();
  compare->footer(
      "For every stage (source, preprocess, infer, output, end_to_end) and every layer step,\n"
      "prints the p50 of A and of B in ms and the change B - A in ms and percent, sorted by\n"
      "the largest absolute change; steps present in only one file come last. Steps are matched\n"
      "by name (a repeated name by its occurrence).\n"
      "Exit codes: 0 compared, 1 a file is missing, not JSON or not an sfrt profile report,\n"
      "2 usage error.");
  return Command{cmd, [args, compare] {
                   if (compare->parsed()) return RunCompare(*args);
                   return ReportError("report", "no subcommand given (run 'sfrt report --help')",
                                      kExitUsage);
                 }};
}

}  // namespace sfrt::tools
