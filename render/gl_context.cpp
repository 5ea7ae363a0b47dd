// gl_context.cpp - OSMesa and EGL headless contexts (see gl_context.h).
#include "render/gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/osmesa.h>

#include <cstring>
#include <vector>

#include "sim/core_error.h"

namespace esim {

void GlContext::loadFunctions(void* (*getProc)(const char*)) {
#define ESIM_GL_LOAD(type, name)                                 \
  gl_.name = reinterpret_cast<type>(getProc("gl" #name));        \
  ESIM_VERIFY(gl_.name != nullptr, "GL context (" + backend_ +   \
                                       "): entry point gl" #name \
                                       " not found; an OpenGL 3.3 core driver is required");
  ESIM_GL_FUNCTIONS(ESIM_GL_LOAD)
#undef ESIM_GL_LOAD
  auto str = [&](GLenum e) {
    const GLubyte* s = gl_.GetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("unknown");
  };
  renderer_ = str(GL_RENDERER);
  version_ = str(GL_VERSION);
  GLint major = 0, minor = 0;
  gl_.GetIntegerv(GL_MAJOR_VERSION, &major);
  gl_.GetIntegerv(GL_MINOR_VERSION, &minor);
  ESIM_VERIFY(
      major > 3 || (major == 3 && minor >= 3),
      "GL context (" + backend_ + "): got OpenGL " + version_ + ", expected a 3.3+ core profile");
}

namespace {

// ---- OSMesa ----

void* osmesaProc(const char* name) { return reinterpret_cast<void*>(OSMesaGetProcAddress(name)); }

class OsMesaContext final : public GlContext {
 public:
  OsMesaContext() {
    backend_ = "osmesa";
    platform_ = "OSMesa";
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_STENCIL_BITS,
                           0,
                           OSMESA_ACCUM_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           3,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    ESIM_VERIFY(ctx_ != nullptr,
                "GL context (osmesa): OSMesaCreateContextAttribs failed to create a 3.3 core "
                "context (is Mesa's libOSMesa with llvmpipe installed?)");
    dummy_.assign(kDummySize * kDummySize * 4, 0);
    makeCurrent();
    loadFunctions(&osmesaProc);
  }
  ~OsMesaContext() override {
    if (ctx_) OSMesaDestroyContext(ctx_);
  }
  void makeCurrent() override {
    ESIM_VERIFY(OSMesaMakeCurrent(ctx_, dummy_.data(), GL_UNSIGNED_BYTE, kDummySize, kDummySize),
                "GL context (osmesa): OSMesaMakeCurrent failed");
  }

 private:
  static constexpr int kDummySize = 16;  // client buffer; drawing goes to our FBOs
  OSMesaContext ctx_ = nullptr;
  std::vector<unsigned char> dummy_;
};

// ---- EGL ----

void* eglProc(const char* name) { return reinterpret_cast<void*>(eglGetProcAddress(name)); }

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

class EglContext final : public GlContext {
 public:
  EglContext() {
    backend_ = "egl";
    // 1. a display without a window system
    const char* clientExt = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    ESIM_VERIFY(hasExtension(clientExt, "EGL_EXT_platform_base"),
                "GL context (egl): EGL_EXT_platform_base is missing from the EGL client");
    auto getPlatformDisplay = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    ESIM_VERIFY(getPlatformDisplay, "GL context (egl): eglGetPlatformDisplayEXT not found");
    std::string tried;
    if (hasExtension(clientExt, "EGL_MESA_platform_surfaceless")) {
      EGLDisplay d =
          getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
      if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr)) {
        display_ = d;
        platform_ = "EGL surfaceless (EGL_MESA_platform_surfaceless)";
      } else {
        tried += " surfaceless: eglInitialize failed;";
      }
    }
    if (display_ == EGL_NO_DISPLAY && hasExtension(clientExt, "EGL_EXT_platform_device")) {
      auto queryDevices =
          reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
      EGLDeviceEXT devices[16];
      EGLint count = 0;
      if (queryDevices && queryDevices(16, devices, &count)) {
        for (EGLint i = 0; i < count && display_ == EGL_NO_DISPLAY; ++i) {
          EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
          if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr)) {
            display_ = d;
            platform_ = "EGL device " + std::to_string(i) + " (EGL_EXT_platform_device)";
          }
        }
      }
      if (display_ == EGL_NO_DISPLAY) tried += " device: no device initialised;";
    }
    ESIM_VERIFY(display_ != EGL_NO_DISPLAY,
                "GL context (egl): no headless EGL display (tried" +
                    (tried.empty() ? std::string(" nothing: neither EGL_MESA_platform_surfaceless "
                                                 "nor EGL_EXT_platform_device is offered")
                                   : tried) +
                    ")");
    // 2. a core 3.3 context, current without a surface
    const char* dpyExt = eglQueryString(display_, EGL_EXTENSIONS);
    ESIM_VERIFY(hasExtension(dpyExt, "EGL_KHR_surfaceless_context"),
                "GL context (egl): display lacks EGL_KHR_surfaceless_context");
    ESIM_VERIFY(eglBindAPI(EGL_OPENGL_API), "GL context (egl): eglBindAPI(EGL_OPENGL_API) failed");
    EGLConfig config = nullptr;
    const EGLint cfgAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint numConfigs = 0;
    if (!eglChooseConfig(display_, cfgAttribs, &config, 1, &numConfigs) || numConfigs < 1) {
      ESIM_VERIFY(hasExtension(dpyExt, "EGL_KHR_no_config_context") ||
                      hasExtension(dpyExt, "EGL_MESA_configless_context"),
                  "GL context (egl): no OpenGL config and no configless contexts");
      config = nullptr;  // EGL_NO_CONFIG_KHR
    }
    const EGLint ctxAttribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                 3,
                                 EGL_CONTEXT_MINOR_VERSION,
                                 3,
                                 EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                 EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                 EGL_NONE};
    ctx_ = eglCreateContext(display_, config, EGL_NO_CONTEXT, ctxAttribs);
    ESIM_VERIFY(ctx_ != EGL_NO_CONTEXT,
                "GL context (egl): eglCreateContext (3.3 core) failed, "
                "EGL error 0x" +
                    hex(eglGetError()));
    makeCurrent();
    loadFunctions(&eglProc);
  }
  ~EglContext() override {
    if (display_ != EGL_NO_DISPLAY) {
      if (eglGetCurrentContext() == ctx_)
        eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      if (ctx_ != EGL_NO_CONTEXT) eglDestroyContext(display_, ctx_);
      // the display is shared per platform inside EGL; terminating it would
      // invalidate other contexts of this process, so it is left initialised
    }
  }
  void makeCurrent() override {
    ESIM_VERIFY(eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx_),
                "GL context (egl): eglMakeCurrent failed, EGL error 0x" + hex(eglGetError()));
  }

 private:
  static std::string hex(EGLint v) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "%x", static_cast<unsigned>(v));
    return buf;
  }
  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext ctx_ = EGL_NO_CONTEXT;
};

}  // namespace

std::unique_ptr<GlContext> createGlContext(const std::string& backend) {
  if (backend == "osmesa") return std::make_unique<OsMesaContext>();
  if (backend == "egl") return std::make_unique<EglContext>();
  throw Error("render.backend: unknown backend '" + backend + "', expected 'osmesa' or 'egl'");
}

bool eglBackendAvailable(std::string* reason) {
  try {
    auto ctx = createGlContext("egl");
    return true;
  } catch (const Error& e) {
    if (reason) *reason = e.what();
    return false;
  }
}

}  // namespace esim
