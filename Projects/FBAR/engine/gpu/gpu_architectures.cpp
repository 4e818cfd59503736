// gpu_code_fit(): the CUDA architectures of a build against a device's compute capability (gpu_architectures.h).
#include "engine/gpu/gpu_architectures.h"

#include <cctype>
#include <sstream>

namespace fbar {
namespace {

std::string trim(const std::string& s) {
  std::size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

bool parse_entry(const std::string& entry, CudaArchitecture& a) {
  std::string s = entry;
  a = CudaArchitecture{};
  auto ends_with = [&](const char* tail) {
    const std::string t(tail);
    return s.size() > t.size() && s.compare(s.size() - t.size(), t.size(), t) == 0;
  };
  if (ends_with("-real")) {
    a.ptx = false;
    s.resize(s.size() - 5);
  } else if (ends_with("-virtual")) {
    a.sass = false;
    s.resize(s.size() - 8);
  }
  if (!s.empty() && (s.back() == 'a' || s.back() == 'f')) {
    a.variant = s.back();
    s.pop_back();
  }
  if (s.size() < 2 || s.size() > 3) return false;
  for (char c : s)
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  const int n = std::stoi(s);
  a.major = n / 10;
  a.minor = n % 10;
  return a.major > 0;
}

std::string capability(int major, int minor) { return std::to_string(major) + "." + std::to_string(minor); }

/// Whether SASS (ptx = false) or PTX (ptx = true) of entry `a` loads on compute capability major.minor.
bool loads(const CudaArchitecture& a, bool ptx, int major, int minor) {
  if (ptx ? !a.ptx : !a.sass) return false;
  if (a.variant == 'a') return major == a.major && minor == a.minor;
  if (a.variant == 'f' || !ptx) return major == a.major && minor >= a.minor;
  return major > a.major || (major == a.major && minor >= a.minor);
}

/// Where one kind of code of entry `a` runs, for the message: "9.0 to 9.x", "9.0 and newer", "9.0 only".
std::string where_it_runs(const CudaArchitecture& a, bool ptx) {
  const std::string cc = capability(a.major, a.minor);
  if (a.variant == 'a') return cc + " only";
  if (a.variant == 'f' || !ptx) return cc + " to " + std::to_string(a.major) + ".x";
  return cc + " and newer";
}

/// "SASS for sm_80 (runs on compute capability 8.0 to 8.x), sm_90 (9.0 to 9.x); PTX for compute_90 (9.0 and newer)".
std::string describe(const std::vector<CudaArchitecture>& archs) {
  std::ostringstream os;
  bool first_item = true;
  for (const bool ptx : {false, true}) {
    bool first_of_kind = true;
    for (const CudaArchitecture& a : archs) {
      if (ptx ? !a.ptx : !a.sass) continue;
      if (first_of_kind) os << (first_item ? "" : "; ") << (ptx ? "PTX for " : "SASS for ");
      else os << ", ";
      os << cuda_architecture_name(a, ptx) << " (" << (first_item ? "runs on compute capability " : "")
         << where_it_runs(a, ptx) << ")";
      first_of_kind = first_item = false;
    }
  }
  return os.str();
}

}  // namespace

std::string cuda_architecture_name(const CudaArchitecture& a, bool ptx) {
  std::string name = (ptx ? "compute_" : "sm_") + std::to_string(a.major * 10 + a.minor);
  if (a.variant != '\0') name += a.variant;
  return name;
}

bool parse_cuda_architectures(const std::string& list, std::vector<CudaArchitecture>& out, std::string& error) {
  out.clear();
  std::string entry;
  std::istringstream in(list);
  while (std::getline(in, entry, list.find(';') != std::string::npos ? ';' : ',')) {
    entry = trim(entry);
    if (entry.empty()) continue;
    CudaArchitecture a;
    if (!parse_entry(entry, a)) {
      error = "CUDA architecture '" + entry + "' is not a number with an optional a/f and -real/-virtual";
      out.clear();
      return false;
    }
    out.push_back(a);
  }
  if (out.empty()) {
    error = "no CUDA architecture in '" + list + "'";
    return false;
  }
  return true;
}

GpuCodeFit gpu_code_fit(const std::string& architectures, int major, int minor) {
  GpuCodeFit fit;
  std::vector<CudaArchitecture> archs;
  std::string error;
  if (!parse_cuda_architectures(architectures, archs, error)) {
    fit.runs = true;  // unknown: loading a kernel decides
    fit.message = "the build's CUDA architectures are unknown (" + error + ")";
    return fit;
  }
  // The newest SASS that loads, else the newest PTX that does (what the driver picks).
  const CudaArchitecture* sass = nullptr;
  const CudaArchitecture* ptx = nullptr;
  auto newer = [](const CudaArchitecture* best, const CudaArchitecture& a) {
    return best == nullptr || a.major * 10 + a.minor > best->major * 10 + best->minor ||
           (a.major * 10 + a.minor == best->major * 10 + best->minor && a.variant != '\0');
  };
  for (const CudaArchitecture& a : archs) {
    if (loads(a, false, major, minor) && newer(sass, a)) sass = &a;
    if (loads(a, true, major, minor) && newer(ptx, a)) ptx = &a;
  }
  const std::string cc = capability(major, minor);
  const std::string rebuild_arch = std::to_string(major * 10 + minor);
  const std::string rebuild = "cmake --preset release -DCMAKE_CUDA_ARCHITECTURES=" + rebuild_arch +
                              " (or =native: the GPUs of the building machine), then cmake --build --preset release";
  if (sass != nullptr) {
    fit.runs = true;
    fit.code = cuda_architecture_name(*sass, false);
    return fit;
  }
  if (ptx != nullptr) {
    fit.runs = fit.jit = true;
    fit.code = cuda_architecture_name(*ptx, true);
    fit.message = "this build has no SASS for compute capability " + cc + ": the driver compiles its PTX (" +
                  fit.code + ") for the GPU at start, so the first start is slower (the driver caches the result). " +
                  "To build for this GPU: " + rebuild;
    return fit;
  }
  fit.message = "this build has no code for compute capability " + cc + ": its CUDA architectures " + architectures +
                " give " + describe(archs) + ". Rebuild for this GPU: " + rebuild;
  return fit;
}

}  // namespace fbar
