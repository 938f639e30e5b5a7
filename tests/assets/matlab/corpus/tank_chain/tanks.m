% five tanks in a row: each drains into the next
n = 5;
k = 0.8;
y0 = zeros(n, 1);
y0(1) = 10;
[t, y] = ode45(@(t, y) cascade(t, y, k, n), linspace(0, 10, 41), y0, ...
               odeset('RelTol', 1e-7, 'AbsTol', 1e-9));
plot(t, y)

function dydt = cascade(t, y, k, n)
dydt = zeros(n, 1);
dydt(1) = -k*y(1);
for i = 2:n
    dydt(i) = k*(y(i-1) - y(i));
end
end
