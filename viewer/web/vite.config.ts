// The page's build: one HTML file, one script and one stylesheet in dist/ with relative paths, so the gateway
// serves it from any folder and nothing is fetched from elsewhere at run time.
import { defineConfig } from "vite";

export default defineConfig({
  base: "./",
  build: { outDir: "dist", emptyOutDir: true, target: "es2022", sourcemap: false, assetsInlineLimit: 0 },
});
