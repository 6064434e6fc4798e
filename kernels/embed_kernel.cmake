# SPDX-License-Identifier: Apache-2.0
# Turns one OpenCL C source into a C++ header holding its bytes, so kernels travel inside the
# binary and are never read from the working directory at run time.
# Called as: cmake -DINPUT=x.cl -DOUTPUT=x_cl.h -DSYMBOL=kBlendSource -P embed_kernel.cmake
file(READ "${INPUT}" content HEX)
string(LENGTH "${content}" hex_length)
math(EXPR byte_count "${hex_length} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${content}")
string(REGEX REPLACE "(0x..,0x..,0x..,0x..,0x..,0x..,0x..,0x..,0x..,0x..,0x..,0x..,)" "\\1\n  "
       bytes "${bytes}")
get_filename_component(source_name "${INPUT}" NAME)
set(text "// Generated from kernels/${source_name} at build time. Do not edit.\n#pragma once\n\n")
string(APPEND text "#include <cstddef>\n\nnamespace drivenshape::kernels {\n")
string(APPEND text "inline constexpr char ${SYMBOL}[] = {\n  ${bytes}0x00};\n")
string(APPEND text "inline constexpr std::size_t ${SYMBOL}Size = ${byte_count};\n")
string(APPEND text "inline constexpr const char* ${SYMBOL}Name = \"${source_name}\";\n}  // namespace drivenshape::kernels\n")
# Rewrite only when the text changed, so dependants do not rebuild needlessly.
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" old)
  if(old STREQUAL text)
    return()
  endif()
endif()
file(WRITE "${OUTPUT}" "${text}")
