// gl_context.h - a headless OpenGL 3.3+ core context: OSMesa or EGL.
//
// Backends:
//   "osmesa" (default): OSMesaCreateContextAttribs with a core profile; on Debian
//            12 Mesa this is GL 4.5 core on llvmpipe. OSMesa needs a client
//            buffer to make the context current; we give it a tiny one and never
//            draw into it (the renderer draws into its own framebuffer object).
//   "egl":   EGL without a window system: EGL_MESA_platform_surfaceless first,
//            then EGL_EXT_platform_device (first device that initialises), with
//            a surfaceless current context (EGL_KHR_surfaceless_context). This
//            path also reaches GPU drivers on render servers.
// Because both draw only into application framebuffer objects, the same Mesa
// driver gives the same pixels through either backend.
// GL entry points are loaded per context into a GlFunctions table (gl_functions.h).
// Ownership: a GlContext owns its native context and display; it is used from
// one thread at a time (makeCurrent() binds it to the calling thread).
#pragma once

#include <memory>
#include <string>

#include "render/gl_functions.h"

namespace esim {

class GlContext {
 public:
  virtual ~GlContext() = default;
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  // binds the context to the calling thread; throws esim::Error on failure
  virtual void makeCurrent() = 0;

  const GlFunctions& gl() const { return gl_; }
  const std::string& backend() const { return backend_; }      // "osmesa" or "egl"
  const std::string& glRenderer() const { return renderer_; }  // GL_RENDERER
  const std::string& glVersion() const { return version_; }    // GL_VERSION
  const std::string& platform() const { return platform_; }    // e.g. "EGL surfaceless"

 protected:
  GlContext() = default;
  // fills gl_ through getProc (throws naming a missing entry point), reads strings
  void loadFunctions(void* (*getProc)(const char*));

  GlFunctions gl_;
  std::string backend_, renderer_, version_, platform_;
};

// creates and makes current a context of the named backend ("osmesa" | "egl");
// throws esim::Error naming the backend and the failing step
std::unique_ptr<GlContext> createGlContext(const std::string& backend);

// true if an EGL context can be created here; otherwise *reason says why
bool eglBackendAvailable(std::string* reason);

}  // namespace esim
