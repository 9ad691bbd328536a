# aarch64 Linux, cross-compiled here and run under qemu-user (tests/platforms/aarch64.sh):
#   cmake -DCMAKE_TOOLCHAIN_FILE=tests/platforms/aarch64-toolchain.cmake -DKDRT_CORE_TESTS_ONLY=ON ...
# The compilers are Debian's aarch64-linux-gnu-gcc and -g++ where installed, else Clang with
# --target=aarch64-linux-gnu on the same cross libraries (libc6-dev-arm64-cross,
# libstdc++-12-dev-arm64-cross): Debian 12's gcc-multilib and g++-aarch64-linux-gnu cannot be
# installed together. KDRT_AARCH64_COMPILER=gcc or clang picks one.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(kdrt_aarch64_root /usr/aarch64-linux-gnu)

set(kdrt_aarch64_compiler "$ENV{KDRT_AARCH64_COMPILER}")
if(NOT kdrt_aarch64_compiler)
  find_program(kdrt_aarch64_gxx aarch64-linux-gnu-g++)
  if(kdrt_aarch64_gxx)
    set(kdrt_aarch64_compiler gcc)
  else()
    set(kdrt_aarch64_compiler clang)
  endif()
endif()
if(kdrt_aarch64_compiler STREQUAL "gcc")
  set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
  set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
  # Catch2 is header-only in the host's /usr/include, which GCC's cross compiler does not search:
  # searched after its own headers, so the host's libc headers never stand in for aarch64's.
  set(CMAKE_CXX_FLAGS_INIT "-idirafter /usr/include")
elseif(kdrt_aarch64_compiler STREQUAL "clang")
  # Clang's aarch64 target searches the cross headers first and the host's /usr/include last.
  set(CMAKE_C_COMPILER clang)
  set(CMAKE_CXX_COMPILER clang++)
  set(CMAKE_C_COMPILER_TARGET aarch64-linux-gnu)
  set(CMAKE_CXX_COMPILER_TARGET aarch64-linux-gnu)
else()
  message(FATAL_ERROR "KDRT_AARCH64_COMPILER is '${kdrt_aarch64_compiler}': gcc or clang")
endif()

# ctest (and Catch2's test discovery at build time) run the programs through qemu.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L ${kdrt_aarch64_root})
