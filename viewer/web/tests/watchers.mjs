// N WebSocket watchers of the viewer's gateway, as N browser tabs would open them, without drawing: for the
// stepping-throughput A/B (tests/viewer/measure.py ab). Usage: node --experimental-websocket watchers.mjs
// WS_URL TOKEN SESSION... ; prints {"ticks": [...per watcher], "errors": [...]} when stdin closes.
const [url, token, ...sessions] = process.argv.slice(2);
const ticks = sessions.map(() => 0);
const errors = [];
const sockets = sessions.map((id, i) => {
  const ws = new WebSocket(url);
  ws.onopen = () => ws.send(JSON.stringify({ session: id, token }));
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "tick") ticks[i]++;
    else if (msg.type === "error") errors.push(msg.message);
  };
  ws.onerror = (e) => errors.push(String(e.message || e));
  return ws;
});
process.stdout.write("open\n");
process.stdin.resume();
process.stdin.on("end", () => {
  for (const ws of sockets) ws.close();
  process.stdout.write(JSON.stringify({ ticks, errors }) + "\n");
  process.exit(0);
});
