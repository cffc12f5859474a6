// The translation unit that a precompiled header is built for (PrecompiledHeaders.cmake).
int rgbd_precompiled_header_host() { return 0; }
