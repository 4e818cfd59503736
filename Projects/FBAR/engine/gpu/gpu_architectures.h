// Whether a build's GPU code runs on a device: CUDA architectures compiled in against a compute capability (host).
//
// A build embeds, per entry of CMAKE_CUDA_ARCHITECTURES (CMake's syntax):
//   "90"          SASS for sm_90 and PTX for compute_90 (CMake's default for an entry without a suffix)
//   "90-real"     SASS for sm_90 only            "90-virtual"  PTX for compute_90 only
//   "90a"         arch-specific: SASS / PTX that runs on compute capability 9.0 only
//   "100f"        family-specific: runs on 10.0, 10.x
// SASS for sm_XY runs on compute capability X.y with y >= Y (the same major version); PTX for compute_XY is
// compiled by the driver at load time (JIT) for any compute capability >= X.Y. A device that neither fits cannot
// load the kernels ("no kernel image is available for execution on the device").
#pragma once

#include <string>
#include <vector>

namespace fbar {

/// One entry of a CMake CUDA architecture list.
struct CudaArchitecture {
  int major = 0;         ///< 9 for "90"
  int minor = 0;         ///< 0 for "90"
  bool sass = true;      ///< machine code (sm_XY) embedded
  bool ptx = true;       ///< PTX (compute_XY) embedded
  char variant = '\0';   ///< 'a' (arch-specific), 'f' (family-specific) or '\0'
};

/// Parses a list of CMake CUDA architecture entries separated by ',' or ';' ("90", "80-real,90-virtual", "90a").
/// Returns false (and `error`) for an entry that is not such a number (e.g. "native" left unresolved).
bool parse_cuda_architectures(const std::string& list, std::vector<CudaArchitecture>& out, std::string& error);

/// What a device of compute capability major.minor loads from a build compiled for `architectures`.
struct GpuCodeFit {
  bool runs = false;
  bool jit = false;      ///< runs by JIT compilation of embedded PTX: the build has no SASS for the device
  std::string code;      ///< what the device loads: "sm_90" (SASS) or "compute_90" (PTX); empty when nothing fits
  /// Why the device cannot run the build and how to rebuild for it (runs == false), or, for jit, a note on the
  /// slower first start; empty otherwise. Names neither the device nor its index: the caller does.
  std::string message;
};

/// The pure decision: the device's compute capability against the architectures compiled in. An architecture
/// list that cannot be parsed gives runs = true (the caller's loading of a kernel decides) with the parse error in
/// `message`.
GpuCodeFit gpu_code_fit(const std::string& architectures, int major, int minor);

/// "sm_90" / "compute_90a" / "sm_100f" for an entry; `ptx` picks the PTX name.
std::string cuda_architecture_name(const CudaArchitecture& a, bool ptx);

}  // namespace fbar
