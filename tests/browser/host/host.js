// The host of Foxglove Studio 1.48's App: what its own web build provides (an app
// configuration, a layout store, the data sources), kept in memory. The layout to show is
// served as /layout.json and selected by the page's `layoutId=patrol` URL parameter; the data
// source comes from the URL as in Foxglove's deep links (`ds=remote-file&ds.url=…`).
/* global React, ReactDOM */
(async function main() {
  const studio = window;
  const settings = new Map();
  const listeners = new Map();
  const appConfiguration = {
    get: (key) => settings.get(key),
    set: async (key, value) => {
      settings.set(key, value);
      for (const cb of listeners.get(key) ?? []) cb(value);
    },
    addChangeListener: (key, cb) => listeners.set(key, [...(listeners.get(key) ?? []), cb]),
    removeChangeListener: (key, cb) =>
      listeners.set(key, (listeners.get(key) ?? []).filter((x) => x !== cb)),
  };
  const data = await (await fetch("/layout.json")).json();
  const now = new Date().toISOString();
  const layouts = new Map([["patrol", {
    id: "patrol", name: "patrol", permission: "CREATOR_WRITE",
    baseline: { data, savedAt: now }, working: undefined, syncInfo: undefined,
  }]]);
  const layoutStorage = {
    list: async () => [...layouts.values()],
    get: async (_ns, id) => layouts.get(id),
    put: async (_ns, layout) => { layouts.set(layout.id, layout); return layout; },
    delete: async (_ns, id) => { layouts.delete(id); },
    importLayouts: async () => {},
    migrateUnnamespacedLayouts: async () => {},
  };
  const dataSources = [
    new studio.RemoteDataSourceFactory(),
    new studio.FoxgloveWebSocketDataSourceFactory(),
    new studio.McapLocalDataSourceFactory(),
  ];
  await studio.initI18n();
  ReactDOM.render(
    React.createElement(studio.App, {
      deepLinks: [window.location.href],
      appConfiguration,
      dataSources,
      layoutStorage,
      extensionLoaders: [],
      enableLaunchPreferenceScreen: false,
      enableGlobalCss: true,
    }),
    document.getElementById("root"),
  );
  window.mrtaHostReady = true;
})().catch((err) => { window.mrtaHostError = String(err && err.stack || err); });
