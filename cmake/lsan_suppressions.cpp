// LeakSanitizer suppressions for third-party leaks, compiled into every executable of a sanitizer build
// (CMakeLists.txt adds this file to the executables that link lumen_options when LUMEN_SANITIZE is on).
// One definition per program: a second one in a library would clash at link time. Leaks in Lumen's own code
// are still reported.
//   libOSMesa.so     Mesa's OSMesaDestroyContext never frees the context's framebuffer record (a few hundred
//                    bytes per context, allocated in OSMesaMakeCurrent).
//   libstdc++.so     Netgen's libraries keep the names they demangle (ngcore::Demangle keeps __cxa_demangle's
//                    realloc'd buffers, 34 of them, 992 bytes) while registering their classes for archiving, in
//                    static initialisers before main. The sanitizer's fast unwinder stops in libstdc++ (built
//                    without frame pointers), so the report's stack is realloc <- libstdc++ and only the module
//                    can be named. Lumen's own allocations are inline (operator new from Lumen's frames) and are
//                    still checked; only allocations made inside libstdc++'s compiled code are not.
extern "C" const char* __lsan_default_suppressions();
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\nleak:libstdc++.so\n"; }
