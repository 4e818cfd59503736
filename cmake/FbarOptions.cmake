# Compiler options shared by every fbar target: warnings, no fast-math, CUDA flags.

add_library(fbar_options INTERFACE)
target_compile_options(fbar_options INTERFACE
  $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wno-unused-parameter>
  $<$<AND:$<COMPILE_LANGUAGE:CXX>,$<BOOL:${FBAR_WARNINGS_AS_ERRORS}>>:-Werror>
  # Host/device mistakes are errors; constexpr host functions are callable from device code.
  $<$<COMPILE_LANGUAGE:CUDA>:--expt-relaxed-constexpr --extended-lambda -Werror=cross-execution-space-call>
  $<$<COMPILE_LANGUAGE:CUDA>:-Xcompiler=-Wall,-Wno-unused-parameter>)
# Fast-math stays off: it changes results (denormals, reciprocal, sqrt) and the validation numbers assume IEEE.

# The CUDA architectures the GPU engine is compiled for, as a list of CMake entries ("90": SASS sm_90 and PTX
# compute_90; "90-real": SASS only; "90-virtual": PTX only), with native / all / all-major resolved to what CMake
# compiles. fbar compares it at start with the visible GPU's compute capability (engine/gpu/gpu_architectures.h).
if(FBAR_ENABLE_CUDA)
  if(CMAKE_CUDA_ARCHITECTURES STREQUAL "native")
    set(FBAR_CUDA_ARCHITECTURES_BUILT "${CMAKE_CUDA_ARCHITECTURES_NATIVE}")
  elseif(CMAKE_CUDA_ARCHITECTURES STREQUAL "all")
    set(FBAR_CUDA_ARCHITECTURES_BUILT "${CMAKE_CUDA_ARCHITECTURES_ALL}")
  elseif(CMAKE_CUDA_ARCHITECTURES STREQUAL "all-major")
    set(FBAR_CUDA_ARCHITECTURES_BUILT "${CMAKE_CUDA_ARCHITECTURES_ALL_MAJOR}")
  else()
    set(FBAR_CUDA_ARCHITECTURES_BUILT "${CMAKE_CUDA_ARCHITECTURES}")
  endif()
endif()
