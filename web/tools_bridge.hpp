#pragma once
// The page's layer over the tools module (tools::ToolsCorePlugin, as `stipple view`'s ImGui
// panel is the window's): the page's commands in (Module.stippleTools.queue: a tool chosen,
// pointer events in canvas pixels, finish, undo, labels, filters, clip mode, GeoJSON to load,
// exports and profile views asked for), and what the page draws and shows out, through
// Module.stippleReport: "tools" (the state: tool, measurements with their values and label text,
// the inspected record, filters, clip mode, the measurements as GeoJSON), "overlay" (lines, dots
// and labels in canvas pixels, after every drawn frame), "pick" and "measure" (events), "export"
// (a file written into the page's file system, for the page to download) and "profile" (a
// profile's image and frame, through Module.stippleToolsProfile).
namespace stipple {
class Engine;
}

namespace stipple::web {

// Applies the page's queued tool commands. Returns whether the view is to be drawn again (a
// measurement, filter or clip changed); `holds_pointer`: the tools hold the pointer (a vertex is
// being dragged), so the camera does not follow it.
bool take_tool_commands(Engine& engine, bool& holds_pointer);
// Reports the tools' state where it changed since the last call (`force`: now), and the overlay
// for the frame just drawn.
void report_tools(Engine& engine, bool force = false);
void report_overlay(Engine& engine);

}  // namespace stipple::web
