# The web build's dependencies (scripts/build-web.sh configures it with emscripten's toolchain
# file). Of the Debian packages only header-only libraries cross over: their headers are exposed
# through a folder of links (never /usr/include itself, whose C library headers are not
# emscripten's), and the targets the modules name are made here as interface libraries. LASzip
# and the tile decoders are the native build's versions compiled to WebAssembly into .deps/.
find_package(Python3 REQUIRED COMPONENTS Interpreter)
set(STIPPLE_WEB_HEADERS ${CMAKE_BINARY_DIR}/host-headers)
file(MAKE_DIRECTORY ${STIPPLE_WEB_HEADERS})
foreach(dir spdlog fmt glm nlohmann)
  if(NOT EXISTS /usr/include/${dir})
    message(FATAL_ERROR "/usr/include/${dir} not found: run scripts/setup.sh --deps")
  endif()
  file(CREATE_LINK /usr/include/${dir} ${STIPPLE_WEB_HEADERS}/${dir} SYMBOLIC)
endforeach()

# Native WebAssembly exceptions: emscripten's JS-emulated ones call through JS frames, which
# JSPI cannot suspend (the library waits for WebGPU callbacks by suspending).
set(STIPPLE_WEB_FLAGS -pthread -fwasm-exceptions)
add_compile_options(${STIPPLE_WEB_FLAGS})
add_link_options(${STIPPLE_WEB_FLAGS})

add_library(stipple_web_headers INTERFACE)
target_include_directories(stipple_web_headers SYSTEM INTERFACE ${STIPPLE_WEB_HEADERS})
# Debian's spdlog is configured for an external fmt (tweakme.h): both header-only here.
target_compile_definitions(stipple_web_headers INTERFACE FMT_HEADER_ONLY=1)
foreach(name spdlog::spdlog glm::glm nlohmann_json::nlohmann_json Threads::Threads)
  add_library(${name} ALIAS stipple_web_headers)
endforeach()

# LASzip 3.5.0 compiled to WebAssembly by scripts/build-web.sh (the native build's Debian
# liblaszip, from its source tarball): the LAZ and COPC readers. Not searched for (emscripten's
# toolchain confines find_library to its sysroot): its one place is .deps/laszip-wasm.
set(STIPPLE_WEB_LASZIP ${CMAKE_SOURCE_DIR}/.deps/laszip-wasm CACHE PATH
  "LASzip built for WebAssembly (scripts/build-web.sh)")
set(LASZIP_LIBRARY ${STIPPLE_WEB_LASZIP}/lib/liblaszip.a)
set(LASZIP_INCLUDE_DIR ${STIPPLE_WEB_LASZIP}/include)
if(NOT EXISTS ${LASZIP_LIBRARY} OR NOT EXISTS ${LASZIP_INCLUDE_DIR}/laszip/laszip_api.h)
  message(FATAL_ERROR "${LASZIP_LIBRARY} not found: run scripts/build-web.sh --deps")
endif()

# The tile decoders, the native build's Debian versions compiled to WebAssembly by
# scripts/build-web.sh (decoders only): imported under the names the native build finds them by,
# so src/io links them the same way.
set(STIPPLE_WEB_DEPS ${CMAKE_SOURCE_DIR}/.deps CACHE PATH
  "where scripts/build-web.sh puts the libraries it builds for WebAssembly")
function(stipple_web_library target dir lib header)
  set(path ${STIPPLE_WEB_DEPS}/${dir})
  if(NOT EXISTS ${path}/lib/${lib} OR NOT EXISTS ${path}/include/${header})
    message(FATAL_ERROR "${path}/lib/${lib} not found: run scripts/build-web.sh --deps")
  endif()
  add_library(${target} STATIC IMPORTED GLOBAL)
  set_target_properties(${target} PROPERTIES IMPORTED_LOCATION ${path}/lib/${lib}
    INTERFACE_INCLUDE_DIRECTORIES ${path}/include)
endfunction()
stipple_web_library(meshoptimizer::meshoptimizer meshopt-wasm libmeshoptimizer.a meshoptimizer.h)
stipple_web_library(draco::draco draco-wasm libdraco.a draco/compression/decode.h)
stipple_web_library(stipple_web_zstd zstd-wasm libzstd.a zstd.h)
stipple_web_library(stipple_web_brotlidec brotli-wasm libbrotlidec.a brotli/decode.h)
set(ZSTD_LIBRARY stipple_web_zstd)
set(BROTLIDEC_LIBRARY stipple_web_brotlidec)
