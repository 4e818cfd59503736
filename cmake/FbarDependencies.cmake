# Dependency lookup: distribution packages only, nothing is downloaded at configure time.

function(fbar_require pkg_found name debian_pkg)
  if(NOT ${pkg_found})
    message(FATAL_ERROR "fbar needs ${name}. Install it, e.g. on Debian/Ubuntu: apt-get install ${debian_pkg}")
  endif()
endfunction()

find_package(Eigen3 3.3 QUIET NO_MODULE)
fbar_require(Eigen3_FOUND "Eigen3" "libeigen3-dev")

find_package(RapidJSON QUIET)
if(NOT RapidJSON_FOUND)
  find_path(RAPIDJSON_INCLUDE_DIR rapidjson/document.h)
  if(RAPIDJSON_INCLUDE_DIR)
    set(RapidJSON_FOUND TRUE)
  endif()
endif()
fbar_require(RapidJSON_FOUND "RapidJSON" "rapidjson-dev")
find_path(FBAR_RAPIDJSON_INCLUDE rapidjson/document.h HINTS ${RAPIDJSON_INCLUDE_DIRS} ${RapidJSON_INCLUDE_DIRS} ${RAPIDJSON_INCLUDE_DIR})
add_library(fbar_rapidjson INTERFACE)
target_include_directories(fbar_rapidjson SYSTEM INTERFACE ${FBAR_RAPIDJSON_INCLUDE})

find_package(HDF5 QUIET COMPONENTS C)
fbar_require(HDF5_FOUND "HDF5 (C)" "libhdf5-dev")

find_package(OpenMP QUIET COMPONENTS CXX)
fbar_require(OpenMP_CXX_FOUND "OpenMP" "libgomp1 (part of gcc)")

# The CUDA runtime of the GPU engine (FBAR_ENABLE_CUDA, top-level CMakeLists.txt); a build without it has the CPU
# reference engine only.
if(FBAR_ENABLE_CUDA)
  find_package(CUDAToolkit REQUIRED)
endif()

if(FBAR_BUILD_TESTS)
  find_package(GTest QUIET)
  fbar_require(GTest_FOUND "GoogleTest" "libgtest-dev")
endif()

# Optional: multi-GPU transport (later issues) and partio (bgeo through the reference library).
find_package(MPI QUIET COMPONENTS CXX)
set(FBAR_HAVE_NCCL FALSE)
if(FBAR_ENABLE_CUDA)  # NCCL moves device memory: only the GPU engine uses it
  find_library(FBAR_NCCL_LIBRARY nccl HINTS ${CUDAToolkit_LIBRARY_DIR})
  find_path(FBAR_NCCL_INCLUDE nccl.h HINTS ${CUDAToolkit_INCLUDE_DIRS})
  if(FBAR_NCCL_LIBRARY AND FBAR_NCCL_INCLUDE)
    set(FBAR_HAVE_NCCL TRUE)
  endif()
endif()
find_library(FBAR_PARTIO_LIBRARY partio)
find_path(FBAR_PARTIO_INCLUDE Partio.h)
if(FBAR_PARTIO_LIBRARY AND FBAR_PARTIO_INCLUDE)
  set(FBAR_HAVE_PARTIO TRUE)
else()
  set(FBAR_HAVE_PARTIO FALSE)
endif()
