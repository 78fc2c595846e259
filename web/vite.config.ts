/// <reference types="vitest/config" />
import { defineConfig } from 'vite';

// The bundle is committed (web/dist) and embedded in the rtcnc binary; the build must give
// the same bytes from the same sources (scripts/hmi.sh check compares them).
export default defineConfig({
  esbuild: { jsx: 'automatic', jsxImportSource: 'preact' },
  build: {
    outDir: 'dist',
    emptyOutDir: true,
    target: 'es2022',
    sourcemap: false,
    chunkSizeWarningLimit: 1024,
    rollupOptions: {
      output: {
        // three.js and uPlot change less often than the HMI: their own files.
        manualChunks: { three: ['three'], uplot: ['uplot'] },
      },
    },
  },
  server: {
    proxy: { '/api': { target: 'http://127.0.0.1:8080', ws: true } },
  },
  test: {
    include: ['test/**/*.test.ts'],
    environment: 'node',
  },
});
