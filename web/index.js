// The sessions list: polls /sessions every second (with the page's own ?token=, if any).
const token = new URLSearchParams(location.search).get('token');
const q = token ? `?token=${encodeURIComponent(token)}` : '';
const body = document.querySelector('#sessions tbody');
const status = document.getElementById('status');

function cell(tr, text) {
  const td = document.createElement('td');
  td.textContent = text;
  tr.appendChild(td);
  return td;
}

async function refresh() {
  try {
    const r = await fetch(`/sessions${q}`, { cache: 'no-store' });
    if (!r.ok) throw new Error(`${r.status} ${await r.text()}`);
    const { sessions } = await r.json();
    body.replaceChildren();
    for (const s of sessions) {
      const tr = document.createElement('tr');
      const a = document.createElement('a');
      a.href = `/view/${encodeURIComponent(s.name)}${q}`;
      a.textContent = s.name;
      cell(tr, '').appendChild(a);
      cell(tr, s.rig);
      cell(tr, s.layout);
      cell(tr, s.active ? 'live' : `ended (${s.end_reason ?? '?'})`);
      cell(tr, String(s.frames));
      cell(tr, String(s.viewers));
      body.appendChild(tr);
    }
    status.textContent = sessions.length ? `${sessions.length} session(s)` : 'no sessions yet: start a tracker (mimic send, a webcam tracker, ...)';
  } catch (e) {
    status.textContent = `cannot list the sessions: ${e.message}`;
  }
}

refresh();
setInterval(refresh, 1000);
