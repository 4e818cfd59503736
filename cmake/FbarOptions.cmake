# Compiler options shared by every fbar target: warnings, no fast-math, CUDA flags.

add_library(fbar_options INTERFACE)
target_compile_options(fbar_options INTERFACE
  $<$<COMPILE_LANGUAGE:CXX>:-Wall -Wextra -Wno-unused-parameter>
  $<$<AND:$<COMPILE_LANGUAGE:CXX>,$<BOOL:${FBAR_WARNINGS_AS_ERRORS}>>:-Werror>
  # Host/device mistakes are errors; constexpr host functions are callable from device code.
  $<$<COMPILE_LANGUAGE:CUDA>:--expt-relaxed-constexpr --extended-lambda -Werror=cross-execution-space-call>
  $<$<COMPILE_LANGUAGE:CUDA>:-Xcompiler=-Wall,-Wno-unused-parameter>)
# Fast-math stays off: it changes results (denormals, reciprocal, sqrt) and the validation numbers assume IEEE.
