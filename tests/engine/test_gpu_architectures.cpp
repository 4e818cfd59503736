// gpu_code_fit() (engine/gpu/gpu_architectures.h): a build's CUDA architectures against a device's compute capability.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "engine/gpu/gpu_architectures.h"

namespace fbar {
namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(GpuArchitectures, ParsesCMakeEntries) {
  std::vector<CudaArchitecture> a;
  std::string error;
  ASSERT_TRUE(parse_cuda_architectures("80-real, 90-virtual", a, error)) << error;  // the compile definition's ","
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a[0].major, 8);
  EXPECT_EQ(a[0].minor, 0);
  EXPECT_TRUE(a[0].sass);
  EXPECT_FALSE(a[0].ptx);
  EXPECT_EQ(a[1].major, 9);
  EXPECT_FALSE(a[1].sass);
  EXPECT_TRUE(a[1].ptx);

  ASSERT_TRUE(parse_cuda_architectures("86;90a;100f-real;120", a, error)) << error;  // CMake's own list separator
  ASSERT_EQ(a.size(), 4u);
  EXPECT_EQ(a[0].major * 10 + a[0].minor, 86);
  EXPECT_TRUE(a[0].sass && a[0].ptx);  // no suffix: SASS and PTX, as CMake compiles it
  EXPECT_EQ(a[1].variant, 'a');
  EXPECT_EQ(cuda_architecture_name(a[1], false), "sm_90a");
  EXPECT_EQ(a[2].major, 10);
  EXPECT_EQ(a[2].variant, 'f');
  EXPECT_FALSE(a[2].ptx);
  EXPECT_EQ(cuda_architecture_name(a[3], true), "compute_120");

  EXPECT_FALSE(parse_cuda_architectures("native", a, error));
  EXPECT_TRUE(contains(error, "native")) << error;
  EXPECT_FALSE(parse_cuda_architectures("", a, error));
  EXPECT_FALSE(parse_cuda_architectures("9", a, error));
  EXPECT_FALSE(parse_cuda_architectures("90-fake", a, error));
}

TEST(GpuArchitectures, DefaultBuildRunsOnHopperOnly) {
  // CMAKE_CUDA_ARCHITECTURES=90 (the presets): SASS sm_90 and PTX compute_90.
  GpuCodeFit h100 = gpu_code_fit("90", 9, 0);
  EXPECT_TRUE(h100.runs);
  EXPECT_FALSE(h100.jit);
  EXPECT_EQ(h100.code, "sm_90");
  EXPECT_TRUE(h100.message.empty());

  // An A100 (8.0) and an RTX 4090 (8.9): neither SASS nor PTX loads on an older GPU.
  for (const int minor : {0, 6, 9}) {
    const GpuCodeFit old = gpu_code_fit("90", 8, minor);
    EXPECT_FALSE(old.runs) << "8." << minor;
    EXPECT_TRUE(old.code.empty());
    const std::string cc = "8." + std::to_string(minor);
    EXPECT_TRUE(contains(old.message, "no code for compute capability " + cc)) << old.message;
    EXPECT_TRUE(contains(old.message, "CUDA architectures 90")) << old.message;
    EXPECT_TRUE(contains(old.message, "cmake --preset release -DCMAKE_CUDA_ARCHITECTURES=8" + std::to_string(minor)))
        << old.message;
    EXPECT_TRUE(contains(old.message, "native")) << old.message;
  }
  const GpuCodeFit a100 = gpu_code_fit("90", 8, 0);
  EXPECT_TRUE(contains(a100.message, "SASS for sm_90 (runs on compute capability 9.0 to 9.x); PTX for compute_90 "
                                     "(9.0 and newer)"))
      << a100.message;

  // A newer GPU (Blackwell 10.0, 12.0) JIT-compiles the embedded compute_90 PTX.
  for (const int major : {10, 12}) {
    const GpuCodeFit newer = gpu_code_fit("90", major, 0);
    EXPECT_TRUE(newer.runs);
    EXPECT_TRUE(newer.jit);
    EXPECT_EQ(newer.code, "compute_90");
    EXPECT_TRUE(contains(newer.message, "PTX (compute_90)")) << newer.message;
    EXPECT_TRUE(contains(newer.message, "-DCMAKE_CUDA_ARCHITECTURES=" + std::to_string(major) + "0")) << newer.message;
  }
}

TEST(GpuArchitectures, RealOnlyHasNoPtxToCompile) {
  // "90-real" (what -arch=sm_90 -code=sm_90 or CMake's native give): SASS alone, nothing for a newer GPU.
  EXPECT_TRUE(gpu_code_fit("90-real", 9, 0).runs);
  const GpuCodeFit b200 = gpu_code_fit("90-real", 10, 0);
  EXPECT_FALSE(b200.runs);
  EXPECT_TRUE(contains(b200.message, "SASS for sm_90 (runs on compute capability 9.0 to 9.x)")) << b200.message;
  EXPECT_FALSE(contains(b200.message, "PTX")) << b200.message;
  // With the PTX beside it ("90-real;90-virtual", the same as "90"), the newer GPU runs it through the JIT.
  const GpuCodeFit jit = gpu_code_fit("90-real;90-virtual", 10, 0);
  EXPECT_TRUE(jit.runs);
  EXPECT_TRUE(jit.jit);
  EXPECT_EQ(jit.code, "compute_90");
  // PTX alone runs everywhere from its version up, always through the JIT.
  const GpuCodeFit ptx_only = gpu_code_fit("80-virtual", 9, 0);
  EXPECT_TRUE(ptx_only.runs && ptx_only.jit);
  EXPECT_FALSE(gpu_code_fit("90-virtual", 8, 0).runs);
}

TEST(GpuArchitectures, SassRunsOnLaterMinorVersionsOfItsMajor) {
  // sm_80 SASS runs on 8.6 and 8.9 (binary compatible within a major version), not on 9.0.
  const GpuCodeFit rtx3090 = gpu_code_fit("80-real", 8, 6);
  EXPECT_TRUE(rtx3090.runs);
  EXPECT_FALSE(rtx3090.jit);
  EXPECT_EQ(rtx3090.code, "sm_80");
  EXPECT_FALSE(gpu_code_fit("86-real", 8, 0).runs);  // not on an earlier minor version
  EXPECT_FALSE(gpu_code_fit("80-real", 9, 0).runs);
  // A list picks the newest SASS that fits, SASS before PTX.
  EXPECT_EQ(gpu_code_fit("80-real;86-real;90", 8, 9).code, "sm_86");
  EXPECT_EQ(gpu_code_fit("80-real;90", 9, 0).code, "sm_90");
  EXPECT_EQ(gpu_code_fit("80;90-real", 9, 0).code, "sm_90");
  const GpuCodeFit mixed = gpu_code_fit("80-real,90", 7, 5);
  EXPECT_FALSE(mixed.runs);
  EXPECT_TRUE(contains(mixed.message, "SASS for sm_80 (runs on compute capability 8.0 to 8.x), sm_90 (9.0 to 9.x); "
                                      "PTX for compute_90 (9.0 and newer)"))
      << mixed.message;
  EXPECT_TRUE(contains(mixed.message, "-DCMAKE_CUDA_ARCHITECTURES=75")) << mixed.message;
}

TEST(GpuArchitectures, ArchAndFamilySpecificCode) {
  // sm_90a / compute_90a: compute capability 9.0 only, neither SASS nor PTX on a newer GPU.
  EXPECT_TRUE(gpu_code_fit("90a", 9, 0).runs);
  EXPECT_EQ(gpu_code_fit("90a", 9, 0).code, "sm_90a");
  EXPECT_FALSE(gpu_code_fit("90a", 10, 0).runs);
  // sm_100f: the 10.x family from 10.0 (10.0, 10.3), not 12.0.
  EXPECT_TRUE(gpu_code_fit("100f", 10, 3).runs);
  EXPECT_FALSE(gpu_code_fit("100f", 10, 3).jit);
  EXPECT_FALSE(gpu_code_fit("100f", 12, 0).runs);
  EXPECT_FALSE(gpu_code_fit("103f", 10, 0).runs);
}

TEST(GpuArchitectures, UnknownListLeavesTheDecisionToTheDriver) {
  // An unresolved or empty list cannot decide: it says so and lets the loaded kernel decide (gpu_check.cu).
  for (const char* list : {"", "native"}) {
    const GpuCodeFit fit = gpu_code_fit(list, 8, 0);
    EXPECT_TRUE(fit.runs) << list;
    EXPECT_FALSE(fit.jit) << list;
    EXPECT_TRUE(contains(fit.message, "unknown")) << fit.message;
  }
}

}  // namespace
}  // namespace fbar
