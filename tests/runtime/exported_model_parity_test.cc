// Model files written by `sfrt export` on another machine, run here against PyTorch's outputs.
// Cross builds (aarch64 under qemu) have no exporter: tools/test-aarch64.sh exports the
// reference networks' ONNX fixtures with the host's sfrt into a directory holding, per case,
// NAME.sfrt, NAME.input.npy (H, W, C) and NAME.output.npy (PyTorch's output), listed in
// cases.txt as "NAME HEIGHT WIDTH". Every case runs on every ISA this CPU has and must agree
// with PyTorch to within 1e-4 of the reference's largest magnitude, as pytorch_parity_test
// requires on the host.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/run_against_reference.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

constexpr double kRelativeTolerance = 1e-4;
constexpr size_t kMinimumCases = 4;  // the four reference networks at least

using ExportedCase = testing::ReferenceCase;

std::string CaseDir() { return SFRT_EXPORTED_MODELS_DIR; }

std::vector<ExportedCase> ReadCases() { return testing::ReadReferenceCases(CaseDir()); }

// Error of `isa`'s output relative to the reference's largest magnitude; infinity on any failure
// (reported by the EXPECTs).
double RelativeErrorAgainstPyTorch(const ExportedCase& c, Isa isa) {
  const std::string stem = CaseDir() + "/" + c.name;
  auto model = Model::LoadFile(stem + ".sfrt");
  auto input = io::ReadNpy(stem + ".input.npy");
  auto expected = io::ReadNpy(stem + ".output.npy");
  EXPECT_TRUE(model.ok()) << model.message();
  EXPECT_TRUE(input.ok()) << input.message();
  EXPECT_TRUE(expected.ok()) << expected.message();
  if (!model.ok() || !input.ok() || !expected.ok()) return INFINITY;
  if (input->shape.size() != 3 || input->shape[0] != c.height || input->shape[1] != c.width) {
    ADD_FAILURE() << stem << ".input.npy is not " << c.height << "x" << c.width << "xC";
    return INFINITY;
  }
  return testing::RelativeErrorOfRun(*model, *input, *expected, isa, c.name);
}

TEST(ExportedModelParity, CaseListNamesTheReferenceNetworks) {
  // Fails (rather than skips) when the host export did not run: parity must never be silent.
  EXPECT_GE(ReadCases().size(), kMinimumCases) << "too few cases in " << CaseDir() << "/cases.txt";
}

TEST(ExportedModelParity, EveryIsaMatchesPyTorchOnEveryExportedCase) {
  const auto cases = ReadCases();
  ASSERT_FALSE(cases.empty());
  for (Isa isa : SupportedIsas()) {
    for (const ExportedCase& c : cases) {
      SCOPED_TRACE(std::string(IsaName(isa)) + " " + c.name);
      EXPECT_LE(RelativeErrorAgainstPyTorch(c, isa), kRelativeTolerance);
    }
  }
}

}  // namespace
}  // namespace sfrt
