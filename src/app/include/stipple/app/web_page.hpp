#pragma once
// `stipple tile --page`: the web viewer (scripts/build-web.sh's stipple.html, the viewer's module
// stipple.mjs and the program it runs, stipple.js and .wasm) copied next to a tileset's
// tileset.json, with an index.html that opens it, so the folder can be served by any static web
// server and opened by link (or the viewer embedded in another page through stipple.mjs).
#include <filesystem>
#include <string>
#include <vector>

namespace stipple::app {

// The viewer's files, needed and optional (the module's TypeScript declarations, for pages that
// embed it).
inline const std::vector<std::string> kWebViewerFiles = {
    "stipple.html", "stipple.mjs", "stipple.js", "stipple.wasm", "stipple-tools.js"};
inline const std::vector<std::string> kWebViewerOptionalFiles = {
    "stipple.worker.js", "stipple-isolation.js", "stipple.d.ts", "stipple.d.mts"};

// The folder holding the web viewer, searched in this order: $STIPPLE_WEB_DIR (when set, it must
// hold the viewer); share/stipple/web beside the binary's bin/ (an install); build-web/ beside
// the binary's folder (the build tree: build/stipple and build-web/); the source tree's
// build-web/ (a build folder elsewhere). Throws naming every place looked at and how to build
// it when none holds the viewer.
std::filesystem::path find_web_viewer();

// Copies the viewer into `dir` (which holds tileset.json) and writes index.html opening
// stipple.html?url=tileset.json; returns the viewer folder used.
std::filesystem::path write_web_page(const std::filesystem::path& dir);

}  // namespace stipple::app
